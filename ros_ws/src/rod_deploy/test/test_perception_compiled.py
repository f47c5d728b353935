"""The perception's compiled and cropped fast paths give the same numbers, bit for bit, as the plain numpy /
OpenCV computations they replace."""
import cv2
import numpy as np

from rod_deploy.perception.crossing_order import (_edge_contrasts, _edge_strengths, _occlusion_probes,
                                                  _pairwise_sum, _perturbed_directions)
from rod_deploy.perception.pipeline import distance_map


def test_pairwise_sum_is_numpys_sum():
    rng = np.random.default_rng(0)
    for n in list(range(0, 300)) + [511, 1000, 4099]:
        x = rng.random((2, n)) * 10.0 ** rng.uniform(-3, 3)
        ref = x.sum(axis=1)
        for r in range(2):
            assert _pairwise_sum(np.ascontiguousarray(x[r]), 0, n) == ref[r]


def _reference_contrasts(grey, centre, directions, wa, wb):
    """The occlusion-edge contrasts from the numpy probes (:func:`_occlusion_probes`, :func:`_edge_strengths`)."""
    probes = []
    for ta, tb in directions:
        probes += [_occlusion_probes(grey.shape, centre, ta, tb, wa, wb),
                   _occlusion_probes(grey.shape, centre, tb, ta, wb, wa)]
    e = _edge_strengths(grey.astype(np.float32), probes)
    return [(ea - eb) / (ea + eb) if np.isfinite(ea) and np.isfinite(eb) and ea + eb > 0 else float('nan')
            for ea, eb in zip(e[0::2], e[1::2])]


def test_compiled_edge_contrasts_equal_the_numpy_probes():
    rng = np.random.default_rng(1)
    finite = 0
    for trial in range(400):
        h, w = rng.integers(80, 240, 2)
        bgr = rng.integers(0, 256, (h, w, 3)).astype(np.uint8)
        grey = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
        centre = rng.uniform([0, 0], [h, w]) if trial % 4 == 0 else rng.uniform([35, 35], [h - 35, w - 35])
        a = rng.uniform(0, 2 * np.pi)
        b = a + rng.uniform(0.05, np.pi)
        dirs = _perturbed_directions(np.array([np.cos(a), np.sin(a)]), np.array([np.cos(b), np.sin(b)]),
                                     np.radians(8.0))
        wa, wb = rng.uniform(1, 22, 2)
        new = _edge_contrasts(bgr, centre, dirs, wa, wb)                # grey converted per probed pixel
        ref = _reference_contrasts(grey, centre, dirs, wa, wb)
        # bit for bit with this machine's OpenBLAS; another BLAS kernel sums in another order (1e-16 relative)
        assert np.allclose(np.array(new), np.array(ref), rtol=1e-9, atol=1e-12, equal_nan=True)
        finite += int(np.isfinite(new).sum())
    assert finite > 1000          # most probe sets lie inside the image


def test_probe_grey_is_opencvs_on_every_colour():
    from numba import njit

    from rod_deploy.perception.crossing_order import _grey

    @njit(cache=False)
    def grey_image(bgr):
        out = np.empty(bgr.shape[:2], np.uint8)
        for r in range(bgr.shape[0]):
            for c in range(bgr.shape[1]):
                out[r, c] = _grey(bgr, r, c)
        return out
    levels = np.arange(256, dtype=np.uint8)
    every = np.stack(np.meshgrid(levels, levels, levels, indexing='ij'), axis=-1).reshape(4096, 4096, 3)
    assert np.array_equal(grey_image(every), cv2.cvtColor(every, cv2.COLOR_BGR2GRAY))


def test_distance_map_equals_opencv_on_the_whole_image():
    rng = np.random.default_rng(3)
    for trial in range(300):
        h, w = rng.integers(1, 300, 2)
        m = np.zeros((h, w), bool)
        for _ in range(rng.integers(0, 8)):
            r, c = rng.integers(0, h), rng.integers(0, w)
            cv2.circle(m.view(np.uint8), (int(c), int(r)), int(rng.integers(1, 60)), 1, -1)
        if trial % 3 == 0:
            m &= rng.random((h, w)) > 0.05
        assert np.array_equal(distance_map(m), cv2.distanceTransform(m.view(np.uint8), cv2.DIST_L2, 3))


def test_gaussian_filter_is_scipys():
    from scipy.ndimage import gaussian_filter1d

    from rod_deploy.perception.centreline import gaussian_filter
    rng = np.random.default_rng(0)
    for sigma in (0.7, 1.0, 1.5, 2.0, 3.3):
        for n in range(1, 120):
            x = rng.normal(size=(n, 2)) * 100 + 300
            for wrap in (True, False):
                mode = 'wrap' if wrap else 'nearest'
                assert np.array_equal(gaussian_filter(x, sigma, wrap), gaussian_filter1d(x, sigma, axis=0, mode=mode))
                assert np.array_equal(gaussian_filter(x[:, 0].copy(), sigma, wrap),
                                      gaussian_filter1d(x[:, 0], sigma, mode=mode))


def test_medians_are_numpys():
    from rod_deploy.perception.centreline import _median
    from rod_deploy.perception.pipeline import _median_evidence
    rng = np.random.default_rng(2)
    for n in range(1, 60):
        x = rng.normal(size=n)
        assert _median(x) == np.median(x)
        ev = rng.integers(0, 256, (20, 20)).astype(np.uint8)
        pts = rng.uniform(0, 19, (n, 2))
        assert _median_evidence(ev, pts) == float(np.median(ev[np.round(pts[:, 0]).astype(int),
                                                                np.round(pts[:, 1]).astype(int)]))


def test_column_medians_are_numpys():
    from rod_deploy.perception.crossing_order import _strand_points, median0
    rng = np.random.default_rng(19)
    for n in range(1, 80):
        for shape in ((n,), (n, 2), (n, 3)):
            v = (rng.normal(size=shape) * 40).astype(np.float32)
            if n % 3 == 0:
                v = np.round(v)                                   # ties
            ref = np.median(v, axis=0)
            out = median0(v)
            assert np.asarray(out).dtype == ref.dtype and np.array_equal(out, ref)
        pts = np.cumsum(rng.normal(size=(n, 2)), axis=0) * 2
        centre, w = rng.normal(size=2) * 5, rng.uniform(1, 6)
        d = np.hypot(pts[:, 0] - centre[0], pts[:, 1] - centre[1])
        near = (d >= 1.5 * w) & (d <= 3.5 * w)
        near = near if near.sum() >= 3 else d >= 1.5 * w
        assert np.array_equal(_strand_points(pts, 0, n - 1, centre, w), pts[near] if near.sum() >= 3 else pts[:0])


def test_colour_sample_and_lookup_are_the_numpy_gathers():
    from rod_deploy.perception.crossing_order import _sample
    from rod_deploy.perception.centreline import lookup
    rng = np.random.default_rng(4)
    for trial in range(100):
        h, w = rng.integers(3, 60, 2)
        img = rng.integers(0, 256, (h, w, 3)).astype(np.uint8)
        pts = rng.uniform(-3, [h + 2, w + 2], (int(rng.integers(0, 50)), 2))
        pts[::3] = np.round(pts[::3]) + 0.5                       # ties: rounded half to even
        r = np.minimum(np.maximum(np.round(pts[:, 0]).astype(np.intp), 1), h - 2)
        c = np.minimum(np.maximum(np.round(pts[:, 1]).astype(np.intp), 1), w - 2)
        flat = img.reshape(-1, 3)
        window = np.array([-w - 1, -w, -w + 1, -1, 0, 1, w - 1, w, w + 1])
        ref = flat[window[:, None] + (r * w + c)[None, :]].astype(np.float32).sum(axis=0) / 9.0
        new = _sample(img, pts)
        assert new.dtype == ref.dtype and np.array_equal(new, ref)
        for image in (img[:, :, 0].copy(), img[:, :, 1] > 128, rng.random((h, w)).astype(np.float32)):
            p = np.round(pts).astype(int)
            ref = image[np.clip(p[:, 0], 0, h - 1), np.clip(p[:, 1], 0, w - 1)]
            new = lookup(image, pts)
            assert new.dtype == ref.dtype and np.array_equal(new, ref)


def test_arc_length_and_resample_are_the_numpy_formulas():
    from rod_deploy.perception.centreline import arc_length, resample
    rng = np.random.default_rng(7)
    for trial in range(2000):
        n = int(rng.integers(1, 60))
        p = np.cumsum(rng.normal(size=(n, 2)), axis=0) * 3
        if trial % 3 == 1:
            p = rng.integers(0, 30, (n, 2)).astype(float)         # repeated points and exact sample hits
        step = float(rng.choice([1.0, 0.5, rng.uniform(0.3, 3)]))
        s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))]) if n > 1 else np.zeros(n)
        assert np.array_equal(arc_length(p), s)
        keep = np.concatenate([[True], np.diff(s) > 1e-9])
        q, s = p[keep], s[keep]
        if len(q) < 2 or s[-1] <= 0:
            ref = q[:1]
        else:
            t = np.linspace(0.0, s[-1], max(2, int(np.ceil(s[-1] / step)) + 1))
            ref = np.stack([np.interp(t, s, q[:, 0]), np.interp(t, s, q[:, 1])], axis=1)
        out = resample(p, step)
        assert out.shape == ref.shape and np.array_equal(out, ref)
    assert np.array_equal(resample(np.full((5, 2), 3.0), 1.0), [[3.0, 3.0]])        # no length: the first point
    import pytest
    with pytest.raises(ValueError, match=r'\(n >= 1, 2\) points'):
        resample(np.zeros((0, 2)), 1.0)


def test_edge_profiles_are_the_remap_of_the_numpy_maps():
    from rod_deploy.perception.centreline import _bilinear, edge_profiles
    rng = np.random.default_rng(8)
    for trial in range(200):
        h, w = rng.integers(2, 120, 2)
        image = rng.integers(0, 256, (h, w)).astype(np.uint8)
        n = int(rng.integers(1, 120))
        pts = rng.uniform(-4, [h + 3, w + 3], (n, 2))        # some samples beyond the border (replicated)
        if trial % 4 == 0:
            pts = np.round(pts * 4) / 4                      # samples on and between pixel centres
        a = rng.uniform(0, 2 * np.pi, n)
        normals = np.stack([np.cos(a), np.sin(a)], axis=1)
        half = rng.uniform(2, 20)
        prof, offsets = edge_profiles(image.astype(np.float32), pts, normals, half)
        rows = (pts[:, 0:1] + offsets[None, :] * normals[:, 0:1]).astype(np.float32)
        cols = (pts[:, 1:2] + offsets[None, :] * normals[:, 1:2]).astype(np.float32)
        ref = cv2.remap(image.astype(np.float32), cols, rows, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        assert prof.dtype == np.float32 and np.array_equal(prof, ref)
        # the uint8 image itself (the pipeline's evidence, no float copy) gives the same profiles
        prof_u8, offsets_u8 = edge_profiles(image, pts, normals, half)
        assert np.array_equal(offsets_u8, offsets) and prof_u8.dtype == np.float32 and np.array_equal(prof_u8, ref)
        # the compiled bilinear sample (end placement) is remap's, on uint8 and float32 images
        for i, j in zip(rng.integers(0, n, 20), rng.integers(0, len(offsets), 20)):
            for img in (image, image.astype(np.float32)):
                assert _bilinear(img, rows[i, j], cols[i, j]) == ref[i, j]


def test_profile_search_is_searchsorted():
    """The edge search's bisection (_search) is np.searchsorted on the profile offsets, values on them included."""
    from rod_deploy.perception.centreline import _search, profile_offsets
    rng = np.random.default_rng(12)
    for trial in range(300):
        offsets = profile_offsets(float(rng.uniform(0.5, 25)))
        values = np.concatenate([rng.uniform(offsets[0] - 2, offsets[-1] + 2, 20), rng.choice(offsets, 5),
                                 [offsets[0], offsets[-1], -np.inf, np.inf]])
        for v in values:
            for right in (False, True):
                assert _search(offsets, float(v), right) == np.searchsorted(offsets, v, 'right' if right else 'left')
    assert _search(profile_offsets(3.0), float('nan'), False) == len(profile_offsets(3.0))


def _place_end_reference(pts, evidence, floor, half_width_px, tangent_px):
    """The numpy / cv2.remap end placement that the compiled ray search (_end_target) replaces."""
    from rod_deploy.perception.centreline import arc_length
    h, w = evidence.shape
    for end in (0, 1):
        p = pts if end == 1 else pts[::-1]
        s = arc_length(p)
        trim = min(0.6 * half_width_px * 2.0, 0.25 * s[-1])
        keep = max(int(np.searchsorted(s, s[-1] - trim, side='right')), 2)
        p, s = p[:keep], s[:keep]
        j = min(max(int(np.searchsorted(s, s[-1] - tangent_px)), 0), len(p) - 2)
        t = p[-1] - p[j]
        nt = np.linalg.norm(t)
        if nt < 1e-9:
            continue
        t /= nt
        reach = trim + 2.0 * half_width_px + 4.0
        for r in (reach, reach + 2.0 * half_width_px):    # one width further where the first finds nothing
            steps = np.arange(0.0, r + 1e-9, 0.25)
            ray = p[-1][None, :] + steps[:, None] * t[None, :]
            inside = (ray[:, 0] >= -0.5) & (ray[:, 0] <= h - 0.5) & (ray[:, 1] >= -0.5) & (ray[:, 1] <= w - 0.5)
            vals = cv2.remap(evidence, ray[:, 1].astype(np.float32)[None], ray[:, 0].astype(np.float32)[None],
                             cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)[0]
            peak = float(vals[:8].max())
            below = (vals < max(0.15 * peak, 0.5 * floor)) & inside
            foot = (vals < max(0.35 * peak, floor)) & inside
            if foot.any() or not inside.all():
                break
        if foot.any():
            k35 = int(np.argmax(foot))
            if below.any() and int(np.argmax(below)) == 0:
                target = 0.0
            else:
                k60 = int(np.argmax(np.append(vals[:k35] < max(0.6 * peak, floor), True)))
                g = -np.gradient(vals)
                lo, hi = max(k60 - 1, 0), min(k35 + 1, len(vals) - 1)
                k = lo + int(np.argmax(g[lo:hi + 1]))
                a, b, c = g[max(k - 1, 0)], g[k], g[min(k + 1, len(g) - 1)]
                denom = a - 2 * b + c
                d = np.clip(np.where(np.abs(denom) > 1e-9, 0.5 * (a - c) / denom if denom else 0.0, 0.0), -0.5, 0.5)
                target = steps[k] + 0.25 * d - half_width_px
        elif not inside.all():
            target = steps[int(np.argmin(inside)) - 1]
        else:
            continue
        if target > 0.5:
            extra = np.arange(1.0, target + 1e-9, 1.0)
            if extra.size == 0 or extra[-1] < target - 1e-6:
                extra = np.append(extra, target)
            p = np.vstack([p, p[-1] + extra[:, None] * t[None, :]])
        elif target < -0.5:
            cut = min(-target, 0.5 * half_width_px + 1.0, 0.3 * s[-1])
            last = np.interp(s[-1] - cut, s, np.arange(len(p)))
            i0 = int(np.floor(last))
            q = p[i0] + (last - i0) * (p[min(i0 + 1, len(p) - 1)] - p[i0])
            p = np.vstack([p[s <= s[-1] - cut], q[None]])
        pts = p if end == 1 else p[::-1]
    return pts


def test_end_placement_is_the_numpy_ray_search():
    from rod_deploy.perception.centreline import RefinedPath, place_ends
    rng = np.random.default_rng(13)
    moved = 0
    for trial in range(300):
        h, w = rng.integers(40, 160, 2)
        evidence = np.zeros((h, w), np.uint8)
        a, b = rng.uniform(-10, [h + 10, w + 10], (2, 2))
        width = int(rng.integers(3, 15))
        cv2.line(evidence, (int(a[1]), int(a[0])), (int(b[1]), int(b[0])), int(rng.integers(40, 255)), width)
        evidence = cv2.GaussianBlur(evidence, (5, 5), 1.0)
        if trial % 3 == 0:
            evidence = cv2.add(evidence, rng.integers(0, 30, (h, w)).astype(np.uint8))
        n = int(rng.integers(3, 80))
        shrink = rng.uniform(0, 0.3)
        pts = a + np.linspace(shrink, 1 - shrink, n)[:, None] * (b - a) + rng.normal(0, 0.3, (n, 2))
        floor, half = float(rng.uniform(5, 30)), 0.5 * width
        out = place_ends(RefinedPath(pts.copy(), float(width), False, np.full(n, np.nan)), evidence, floor, half,
                         max(4.0, width)).points
        ref = _place_end_reference(pts.copy(), evidence.astype(np.float32), floor, half, max(4.0, width))
        assert out.shape == ref.shape and np.array_equal(out, ref)
        moved += not np.array_equal(out, pts)
    assert moved > 200


def test_smoothing_and_tangents_are_the_numpy_formulas():
    from scipy.ndimage import gaussian_filter1d

    from rod_deploy.perception.centreline import smooth, tangents
    rng = np.random.default_rng(14)
    for trial in range(600):
        n = int(rng.integers(2, 90))
        p = np.cumsum(rng.normal(size=(n, 2)), axis=0) * 3 + 100
        if trial % 5 == 0:
            p[1:3] = p[0]                                    # repeated points: zero tangents
        closed = bool(trial % 2) and n > 3
        if closed:
            p[-1] = p[0]
        sigma = float(rng.choice([1.0, 1.5, 2.0, rng.uniform(0.5, 4)]))
        if n < 3:
            ref = p.copy()
        elif closed:
            out = gaussian_filter1d(p[:-1], sigma, axis=0, mode='wrap')
            ref = np.vstack([out, out[:1]])
        else:
            pad = min(n - 1, int(np.ceil(4 * sigma)))
            ext = np.vstack([2 * p[0] - p[pad:0:-1], p, 2 * p[-1] - p[-2:-pad - 2:-1]])
            ref = gaussian_filter1d(ext, sigma, axis=0, mode='nearest')[pad:pad + n]
        assert np.array_equal(smooth(p, sigma, closed), ref)
        if closed:
            t = np.roll(p[:-1], -1, axis=0) - np.roll(p[:-1], 1, axis=0)
            t = np.vstack([t, t[:1]])
        else:
            t = np.gradient(p, axis=0)
        norm = np.linalg.norm(t, axis=1, keepdims=True)
        norm[norm == 0] = 1.0
        assert np.array_equal(tangents(p, closed), t / norm)


def test_lab_conversion_of_a_row_is_that_of_a_column():
    from rod_deploy.perception.crossing_order import _lab
    rng = np.random.default_rng(15)
    for trial in range(300):
        n = int(rng.integers(1, 2000))
        px = rng.integers(0, 9 * 255 + 1, (n, 3)).astype(np.float32) / np.float32(9.0)   # 3x3 means, as sampled
        ref = cv2.cvtColor(px.reshape(-1, 1, 3) / 255.0, cv2.COLOR_BGR2Lab).reshape(-1, 3)
        assert np.array_equal(_lab(px), ref)


def test_background_medians_and_otsu_are_the_numpy_formulas():
    from rod_deploy.perception.segmentation import _channel_medians, _otsu
    rng = np.random.default_rng(16)
    for trial in range(500):
        n = int(rng.integers(1, 400))
        px = (rng.integers(0, 256, (n, 3)) if trial % 2 else rng.integers(100, 104, (n, 3))).astype(np.uint8)
        median = np.empty(3)
        spread = _channel_medians(px, median)
        ref = np.median(px, axis=0)
        assert np.array_equal(median, ref) and spread == np.abs(px - ref).max()
        hist = rng.integers(0, 10 ** int(rng.integers(1, 6)), 256).astype(float)
        hist[rng.random(256) < rng.uniform(0, 1)] = 0
        p = hist / max(hist.sum(), 1.0)
        omega, mu = np.cumsum(p), np.cumsum(p * np.arange(256))
        with np.errstate(divide='ignore', invalid='ignore'):
            between = (mu[-1] * omega - mu) ** 2 / (omega * (1.0 - omega))
        between[~np.isfinite(between)] = -1.0
        assert _otsu(hist) == float(np.argmax(between))


def test_median_blur_is_opencvs():
    """The running-histogram median filter gives cv2.medianBlur's image (border replicated), on random and smooth
    images of every size the background estimate meets (down to 1 x 1, windows larger than the image), and on
    the 1/8-scale mBEST-like background with its k = 15; bad input is refused."""
    import pytest

    from rod_deploy.perception.segmentation import median_blur
    rng = np.random.default_rng(30)
    for trial in range(400):
        h, w = (int(v) for v in rng.integers(1, 140, 2))
        k = int(rng.choice([3, 5, 7, 9, 11, 13, 15]))
        img = rng.integers(0, 256, (h, w, 3)).astype(np.uint8)
        if trial % 2:
            img = cv2.GaussianBlur(img, (0, 0), 3)          # smooth: long runs of near-equal medians
        if trial % 5 == 0:
            img[:] = img[0, 0]                              # uniform: every window the same value
        assert np.array_equal(median_blur(img, k), cv2.medianBlur(img, k)), (trial, h, w, k)
    img = rng.integers(0, 256, (84, 112, 3)).astype(np.uint8)
    img = cv2.resize(cv2.resize(img, (14, 10)), (112, 84), interpolation=cv2.INTER_LINEAR)
    assert np.array_equal(median_blur(img, 15), cv2.medianBlur(img, 15))
    with pytest.raises(ValueError, match='odd k'):
        median_blur(img, 4)
    with pytest.raises(ValueError, match='uint8'):
        median_blur(img.astype(np.float32), 5)


def test_batch_colours_are_the_medians_of_each_set():
    """colour_sampler(...).batch (all sets' medians in one compiled call) gives, set by set, median0 of the set's
    a*b* colours (float32, bit for bit), and None for an empty set."""
    from rod_deploy.perception.crossing_order import _lab_ab, _sample, colour_sampler, median0
    rng = np.random.default_rng(32)
    bgr = rng.integers(0, 256, (120, 160, 3)).astype(np.uint8)
    sampler = colour_sampler(bgr)
    for trial in range(300):
        sets = [rng.uniform(-2, 125, (int(rng.integers(0, 40)), 2)) for _ in range(int(rng.integers(1, 12)))]
        for points, colour in zip(sets, sampler.batch(sets)):
            if not len(points):
                assert colour is None
                continue
            ref = median0(_lab_ab(_sample(bgr, points)))
            assert colour.dtype == ref.dtype == np.float32 and np.array_equal(colour, ref), trial
    assert sampler.batch([np.zeros((0, 2))]) == [None]


def test_zones_are_the_numpy_discs():
    from rod_deploy.perception.pipeline import _in_zones
    rng = np.random.default_rng(17)
    for trial in range(200):
        pts = rng.uniform(0, 100, (int(rng.integers(6, 300)), 2))
        k = int(rng.integers(0, 6))
        centres, radii = rng.uniform(0, 100, (k, 2)), rng.uniform(0, 30, k)
        if k:
            pts[:k] = centres + radii[:, None] * np.array([0.6, 0.8])    # on a circle: hypot == radius
        ref = np.zeros(len(pts), bool)
        for c, r in zip(centres, radii):
            ref |= np.hypot(pts[:, 0] - c[0], pts[:, 1] - c[1]) <= r
        assert np.array_equal(_in_zones(pts, centres.reshape(-1, 2), radii), ref)


def test_hermite_connector_is_the_numpy_formula():
    from rod_deploy.perception.traversal import hermite_connector
    rng = np.random.default_rng(9)
    for trial in range(2000):
        p0, p1 = rng.uniform(0, 900, 2), rng.uniform(0, 900, 2)
        if trial % 5 == 0:
            p1 = p0 + rng.normal(size=2) * 3
        a, b = rng.uniform(0, 6.3, 2)
        t0, t1 = np.array([np.cos(a), np.sin(a)]), np.array([np.cos(b), np.sin(b)])
        d = float(np.linalg.norm(p1 - p0))
        s = np.linspace(0.0, 1.0, max(2, int(np.ceil(d)) + 1))[:, None]
        ref = ((2 * s ** 3 - 3 * s ** 2 + 1) * p0 + (s ** 3 - 2 * s ** 2 + s) * (d * t0)
               + (-2 * s ** 3 + 3 * s ** 2) * p1 + (s ** 3 - s ** 2) * (d * t1))
        out = hermite_connector(p0, t0, p1, t1)
        assert out.shape == ref.shape and np.array_equal(out, ref)


def test_path_length_is_numpys_sum():
    from rod_deploy.perception.centreline import path_length
    rng = np.random.default_rng(10)
    for n in range(0, 400):
        p = np.cumsum(rng.normal(size=(n, 2)), axis=0) * 3
        ref = float(np.sum(np.hypot(*np.diff(p, axis=0).T))) if n > 1 else 0.0
        assert path_length(p) == ref


def test_level_counts_are_calchist():
    from rod_deploy.perception.segmentation import _count_levels
    rng = np.random.default_rng(11)
    for trial in range(30):
        s = rng.integers(0, 256, rng.integers(1, 300, 2)).astype(np.uint8)
        for view in (s, s[::2, ::2]):
            hist = np.zeros(256)
            _count_levels(view, hist)
            ref = cv2.calcHist([np.ascontiguousarray(view)], [0], None, [256], [0, 256]).ravel().astype(np.float64)
            assert np.array_equal(hist, ref)


def test_one_colour_evidence_is_the_table_difference():
    from rod_deploy.perception.segmentation import foreground_evidence
    rng = np.random.default_rng(12)
    img = rng.integers(0, 256, (37, 53, 3)).astype(np.uint8)
    for background in ((0.0, 0.0, 0.0), (1.0, 3.0, 3.0), (254.6, 12.5, 13.5), (128.2, 255.0, 0.4)):
        grey = img.astype(np.int64) - np.array([round(v) for v in background])
        for method, ref in (('contrast', np.abs(grey)), ('dark', np.maximum(-grey, 0)), ('bright', np.maximum(grey, 0))):
            assert np.array_equal(foreground_evidence(img, background, method), ref.max(axis=2).astype(np.uint8))


def _branch_geometry_reference(points, skip_px, fit_px, max_fraction=0.45):
    """The numpy branch geometry that the compiled one replaces."""
    import math

    from rod_deploy.perception.centreline import arc_length
    points = points[:int(2 * (skip_px + fit_px)) + 3]
    s = arc_length(points)
    skip = min(skip_px, max_fraction * s[-1])
    i0 = min(int(s.searchsorted(skip)), len(points) - 1)
    i1 = min(max(int(s.searchsorted(s[i0] + fit_px)), i0 + 1), len(points) - 1)
    if i1 <= i0:
        i0 = max(0, len(points) - 1)
        d = points[0] - points[-1] if len(points) > 1 else np.array([0.0, 1.0])
        norm = np.linalg.norm(d)
        return i0, (d / norm if norm > 0 else np.array([0.0, 1.0])), math.inf
    section = points[i0:i1 + 1]
    centred = section - section.mean(axis=0)
    (a, b), (_, c) = (centred.T @ centred).tolist()
    if b == 0.0:
        d = np.array([1.0, 0.0]) if a > c else np.array([0.0, 1.0])
    else:
        theta = 0.5 * math.atan2(2.0 * b, a - c)
        d = np.array([math.cos(theta), math.sin(theta)])
    side = float(np.dot(d, points[i0] - points[i1]))          # its sign orients d; ~0: either orientation
    return i0, (-d if side < 0 else d), side


def test_branch_geometry_is_the_numpy_formula():
    """The compiled scatter and dot products reproduce numpy / OpenBLAS with running fused multiply-adds (bit for
    bit on the machine they were written on); under another BLAS kernel (`scripts/test_other_kernels.sh`) the
    reference sums in another order, so the comparison allows 1e-9."""
    from rod_deploy.perception.bending_energy_pairing import branch_geometry
    rng = np.random.default_rng(18)
    for trial in range(5000):
        n = int(rng.integers(1, 60))
        if trial % 2:
            p = np.cumsum(rng.choice([-1.0, 0.0, 1.0], (n, 2)), axis=0) + rng.integers(0, 500, 2)   # pixel chains
        else:
            p = np.cumsum(rng.normal(size=(n, 2)), axis=0) + 300
        if trial % 7 == 0:
            p[:] = p[0]
        skip, fit = rng.uniform(0, 15), rng.uniform(1, 15)
        i0, d = branch_geometry(p, skip, fit)
        j0, e, side = _branch_geometry_reference(p, skip, fit)
        same = np.allclose(d, e, rtol=0, atol=1e-9) or (abs(side) < 1e-9 and np.allclose(d, -e, rtol=0, atol=1e-9))
        assert i0 == j0 and same, (trial, d, e, side)


def test_colour_cut_is_the_numpy_formula():
    from rod_deploy.perception.crossing_order import median0
    from rod_deploy.perception.traversal import _best_colour_cut
    rng = np.random.default_rng(20)
    cuts = 0
    for trial in range(600):
        n = int(rng.integers(8, 200))
        win = int(rng.integers(3, 12))
        a, b = rng.normal(size=2) * 30, rng.normal(size=2) * 30           # two colours, a step somewhere
        step_at = int(rng.integers(0, n))
        col = np.where(np.arange(n)[:, None] < step_at, a, b) + rng.normal(size=(n, 2)) * rng.uniform(0.5, 15)
        col = col.astype(np.float32)
        idx = np.unique(rng.integers(0, 3 * n, n))
        if len(idx) < 2 * win:
            continue
        col = col[:len(idx)]
        s = np.cumsum(rng.uniform(0.5, 2.0, 3 * n))
        min_length, sep = float(rng.uniform(0, s[-1] / 3)), float(rng.uniform(5, 15))
        # the numpy formula it replaces
        cc = np.vstack([[0.0, 0.0], np.cumsum(col, axis=0)])
        k = np.arange(win, len(idx) - win + 1)
        d = np.linalg.norm((cc[k] - cc[k - win]) / win - (cc[k + win] - cc[k]) / win, axis=1)
        cut_at = (idx[k - 1] + idx[k]) // 2
        ok = (s[cut_at] >= min_length) & (s[-1] - s[cut_at] >= min_length)
        ref = -1
        if ok.any():
            j = int(np.argmax(np.where(ok, d, -1.0)))
            if d[j] >= 2.5 * sep and all(np.mean(np.linalg.norm(part - median0(part), axis=1) < 1.5 * sep) >= 0.8
                                         for part in (col[:k[j]], col[k[j]:])):
                ref = int(cut_at[j])
        assert _best_colour_cut(col, idx.astype(np.int64), s, win, min_length, 2.5 * sep, 1.5 * sep) == ref
        cuts += ref >= 0
    assert cuts > 50


def test_edge_correction_is_the_numpy_formula():
    from rod_deploy.perception.centreline import _edge_correction
    rng = np.random.default_rng(21)
    applied = 0
    for trial in range(1000):
        n = int(rng.integers(1, 120))
        idx = np.arange(0, n, 2)
        if idx[-1] != n - 1:
            idx = np.append(idx, n - 1)
        o_l = rng.normal(-5, rng.uniform(0.1, 3), len(idx))
        o_r = rng.normal(5, rng.uniform(0.1, 3), len(idx))
        o_l[rng.random(len(idx)) < rng.uniform(0, 0.5)] = np.nan
        excluded = rng.random(len(idx)) < rng.uniform(0, 0.5)
        # the numpy formula it replaces
        width, centre = o_r - o_l, 0.5 * (o_l + o_r)
        ok = np.isfinite(width) & ~excluded
        if ok.sum() >= 3:
            w_med = float(np.median(width[ok]))
            ok &= (width > 0.6 * w_med) & (width < 1.4 * w_med) & (np.abs(centre) < 0.35 * w_med + 1.0)
        ref_widths = np.full(n, np.nan)
        ref_widths[idx[ok]] = width[ok]
        delta, widths = np.empty(n), np.empty(n)
        w_obj = _edge_correction(idx, o_l, o_r, excluded, delta, widths)
        assert np.array_equal(widths, ref_widths, equal_nan=True)
        if ok.sum() >= 3:
            assert w_obj == float(np.median(width[ok]))
            assert np.array_equal(delta, np.interp(np.arange(n), idx[ok], centre[ok]))
            applied += 1
        else:
            assert np.isnan(w_obj)
    assert applied > 300


def test_foreign_end_trimming_is_the_numpy_formula():
    from rod_deploy.perception.crossing_order import median0
    from rod_deploy.perception.traversal import TracedObject, trim_foreign_ends
    rng = np.random.default_rng(22)
    trimmed = 0
    for trial in range(400):
        n = int(rng.integers(8, 300))
        pts = np.cumsum(rng.uniform(0.5, 1.5, (n, 2)), axis=0)
        passes = [(0, int(a), int(a) + 5) for a in rng.integers(0, n - 5, int(rng.integers(0, 3)))]
        colours = rng.normal(size=(n, 2)).astype(np.float32) * 3
        for end in (slice(0, int(rng.integers(0, 30))), slice(n - int(rng.integers(0, 30)), n)):
            colours[end] += np.float32(rng.uniform(0, 80))                     # foreign ends, sometimes
        table = {tuple(p): c for p, c in zip(pts.tolist(), colours)}

        def colours_at(points):
            return np.array([table[tuple(p)] for p in points.tolist()], np.float32)
        w, sep = float(rng.uniform(1, 6)), 12.0
        out = trim_foreign_ends(TracedObject(pts, False, passes), colours_at, w, sep)
        # the numpy formula it replaces
        s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
        reach = 4.0 * w
        lo, hi = 0, n - 1
        if s[-1] >= 4 * reach:
            body = np.flatnonzero((s > reach) & (s < s[-1] - reach))[::max(1, int(0.5 * w))]
            first = min((a for _, a, _ in passes), default=n)
            last = max((b for _, _, b in passes), default=-1)
            head = np.flatnonzero((s <= reach) & (np.arange(n) < first))
            tail = np.flatnonzero((s >= s[-1] - reach) & (np.arange(n) > last))
            col = colours_at(pts[np.concatenate([body, head, tail])])
            foreign = np.linalg.norm(col[len(body):] - median0(col[:len(body)]), axis=1) > 2.5 * sep
            fh, ft = foreign[:len(head)], foreign[len(head):][::-1]
            k = np.flatnonzero(fh & (np.cumsum(fh) / np.arange(1, len(fh) + 1) >= 0.5))
            lo = int(head[k[-1]]) + 1 if len(k) else 0
            k = np.flatnonzero(ft & (np.cumsum(ft) / np.arange(1, len(ft) + 1) >= 0.5))
            hi = int(tail[::-1][k[-1]]) - 1 if len(k) else n - 1
        assert np.array_equal(out.points, pts[lo:hi + 1])
        trimmed += (lo, hi) != (0, n - 1)
    assert trimmed > 100


def test_nearest_distances_are_the_kd_trees():
    from scipy.spatial import cKDTree

    from rod_deploy.perception.nearest import nearest_distances
    rng = np.random.default_rng(12)
    for trial in range(600):
        n, m = rng.integers(1, 300, 2)
        kind = trial % 4
        if kind == 0:        # integer pixels: many exact ties and distances equal to the bound
            data, queries = rng.integers(0, 40, (n, 2)).astype(float), rng.integers(-5, 45, (m, 2)).astype(float)
        elif kind == 1:      # the pipeline's full-resolution points of a half-resolution skeleton
            data, queries = rng.integers(0, 80, (n, 2)) + 0.5, rng.integers(-5, 85, (m, 2)) / 2.0
        elif kind == 2:
            data, queries = rng.uniform(0, 200, (n, 2)), rng.uniform(-20, 220, (m, 2))
        else:                # a path and points beside it
            s = np.cumsum(rng.uniform(0.2, 1.5, n))
            data = np.stack([60 + 30 * np.sin(s / 15), s], axis=1)
            queries = data[rng.integers(0, n, m)] + rng.normal(0, 5, (m, 2))
        bound = (rng.uniform(0.5, 30), float(rng.integers(1, 12)), float(np.sqrt(rng.integers(1, 100))), np.inf,
                 1e-3)[trial % 5]
        ref = cKDTree(data).query(queries, distance_upper_bound=bound)[0]
        assert np.array_equal(nearest_distances(data, queries, bound), ref), trial


def test_neighbour_table_is_the_index_image_lookup():
    from rod_deploy.perception.skeleton_graph import _OFFSETS, _neighbour_table
    rng = np.random.default_rng(13)
    for trial in range(400):
        h, w = rng.integers(1, 60, 2)
        skeleton = rng.random((h, w)) < rng.uniform(0.02, 0.9)
        flat = np.flatnonzero(skeleton)
        if not flat.size:
            continue
        rows, cols = np.divmod(flat, w)
        index = np.full((h + 2, w + 2), -1)                   # pixel numbers in a padded image
        index[rows + 1, cols + 1] = np.arange(flat.size)
        ref = np.stack([index[rows + 1 + dr, cols + 1 + dc] for dr, dc in _OFFSETS], axis=1)
        assert np.array_equal(_neighbour_table(flat, w, _OFFSETS), ref), trial


def _numpy_point_to_polyline(points, curve):
    """Distance from each point to the polyline, the numpy broadcast (the evaluation's former code)."""
    a, b = curve[:-1], curve[1:]
    ab = b - a
    ab2 = np.maximum((ab ** 2).sum(axis=1), 1e-12)
    p = points[:, None, :]
    t = np.clip(((p - a[None]) * ab[None]).sum(axis=2) / ab2[None], 0.0, 1.0)
    q = a[None] + t[..., None] * ab[None]
    return np.sqrt(((p - q) ** 2).sum(axis=2)).min(axis=1)


def test_point_to_polyline_distances_are_the_numpy_ones():
    """The compiled point-to-polyline distance of the centreline error (benchmarks' RMS) equals the numpy
    broadcast, bit for bit, on random walks with repeated vertices, and the closed form on a square."""
    from rod_deploy.perception.evaluation import _point_to_polyline
    rng = np.random.default_rng(3)
    for _ in range(40):
        curve = np.cumsum(rng.normal(size=(int(rng.integers(2, 300)), 2)), axis=0)
        curve[1:3] = curve[1]              # a repeated vertex (a zero-length segment) where there are 3+
        points = rng.normal(size=(int(rng.integers(1, 400)), 2)) * 8.0
        assert np.array_equal(_point_to_polyline(points, curve), _numpy_point_to_polyline(points, curve))
    square = np.array([(0.0, 0.0), (0.0, 10.0), (10.0, 10.0), (10.0, 0.0)])
    pts = np.array([(5.0, 5.0), (-3.0, 4.0), (13.0, 14.0), (5.0, 9.0)])
    assert np.allclose(_point_to_polyline(pts, square), [5.0, 3.0, 5.0, 1.0])
