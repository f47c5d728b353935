"""One progress bar for a sequence of labelled simulations (``rod-deploy correct``, ``rod-deploy plan --refine``)."""
from contextlib import contextmanager


@contextmanager
def simulations_progress(quiet=False):
    """Yields ``progress(label, k, total)`` for ``ForwardModel``: a tqdm bar reset for each new label (None if
    ``quiet``); the bar is closed on exit."""
    if quiet:
        yield None
        return
    from tqdm import tqdm
    bar = tqdm(unit='step', disable=None, mininterval=0.5)

    def progress(label, k, total):
        if bar.desc != f'simulate: {label}':
            bar.reset(total=total)
            bar.set_description(f'simulate: {label}')
        bar.update(k - bar.n)

    try:
        yield progress
    finally:
        bar.close()
