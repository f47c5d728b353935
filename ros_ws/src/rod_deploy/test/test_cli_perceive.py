"""`rod-deploy perceive`: files, mapping options, timing, and one-line errors for bad inputs."""
import argparse
import importlib.util
import sys

import cv2
import numpy as np
import pytest

from rod_deploy.cli import perceive
from rod_deploy.cli.main import CliError
from rod_deploy.perception.evaluation import centreline_rms
from rod_deploy.perception.path_io import read_path_csv, read_pattern_file
from rod_deploy.perception.synthetic import draw_strokes, example_curves

CURVE = example_curves(400)['alpha']


def cli(argv):
    """Run like `rod-deploy` does (main.main once every subcommand module exists)."""
    if importlib.util.find_spec('rod_deploy.cli.grasp') is not None:
        from rod_deploy.cli.main import main
        return main(argv)
    parser = argparse.ArgumentParser(prog='rod-deploy')
    perceive.register(parser.add_subparsers(dest='command', required=True))
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except CliError as exc:
        print(f'rod-deploy {args.command}: error: {exc}', file=sys.stderr)
        return 2


@pytest.fixture(scope='module')
def stroke_png(tmp_path_factory):
    path = tmp_path_factory.mktemp('img') / 'stroke.png'
    cv2.imwrite(str(path), draw_strokes((400, 400), [CURVE], [6.0], [(40, 30, 30)], noise_std=2))
    return path


def test_path_csv_pattern_overlay_and_timing(stroke_png, tmp_path, capsys):
    out, pattern, overlay = tmp_path / 'path.csv', tmp_path / 'pattern.txt', tmp_path / 'overlay.png'
    code = cli(['perceive', '--image', str(stroke_png), '--m-per-px', '0.0005', '--out', str(out),
                '--pattern', str(pattern), '--overlay', str(overlay), '--timing', '--repeats', '3'])
    text = capsys.readouterr().out
    assert code == 0
    assert 'timing: median' in text and 'ms per image over 3 runs' in text
    assert out.read_text().startswith('object,row,col,x,y\n')
    paths = read_path_csv(out)
    assert list(paths) == [0]
    px, xy = paths[0]
    assert centreline_rms(px, CURVE)['rms_px'] < 1.0
    # default origin: bottom-left pixel centre, x = (col - 0) s, y = (399 - row) s
    assert np.allclose(xy[:, 0], px[:, 1] * 0.0005, atol=2e-6)
    assert np.allclose(xy[:, 1], (399 - px[:, 0]) * 0.0005, atol=2e-6)
    assert np.allclose(read_pattern_file(pattern)[:, :2], xy, atol=2e-6)
    assert cv2.imread(str(overlay)).shape == (400, 400, 3)


def test_homography_and_origin(stroke_png, tmp_path):
    h = tmp_path / 'H.txt'
    h.write_text('0.001 0 0\n0 -0.001 0.4\n0 0 1\n')                  # x = col mm, y = (400 - row) mm
    assert cli(['perceive', '--image', str(stroke_png), '--homography', str(h), '--out', str(tmp_path / 'a.csv')]) == 0
    assert cli(['perceive', '--image', str(stroke_png), '--m-per-px', '0.001', '--origin', '400', '0',
                '--out', str(tmp_path / 'b.csv')]) == 0
    (pa, xa), (pb, xb) = read_path_csv(tmp_path / 'a.csv')[0], read_path_csv(tmp_path / 'b.csv')[0]
    assert np.allclose(xa, xb, atol=2e-6)


def test_without_mapping_xy_are_pixels(stroke_png, tmp_path, capsys):
    assert cli(['perceive', '--image', str(stroke_png), '--out', str(tmp_path / 'p.csv')]) == 0
    assert 'x and y are in pixels' in capsys.readouterr().out
    px, xy = read_path_csv(tmp_path / 'p.csv')[0]
    assert np.allclose(xy[:, 0], px[:, 1], atol=1e-3)


@pytest.mark.parametrize('make, message', [
    (lambda d: d / 'missing.png', 'does not exist'),
    (lambda d: (d / 'empty.png').write_bytes(b'') and d / 'empty.png' or d / 'empty.png', 'empty'),
    (lambda d: (d / 'junk.png').write_bytes(b'not an image') and d / 'junk.png', 'cannot read'),
    (lambda d: cv2.imwrite(str(d / 'blank.png'), np.full((50, 60), 255, np.uint8)) and d / 'blank.png',
     'no stroke'),
])
def test_bad_images_give_one_line_errors(tmp_path, capsys, make, message):
    path = make(tmp_path)
    assert cli(['perceive', '--image', str(path), '--out', str(tmp_path / 'p.csv')]) == 2
    text = capsys.readouterr().err
    assert 'rod-deploy perceive: error:' in text and message in text
    assert not (tmp_path / 'p.csv').exists()


def test_bad_mapping_and_options(stroke_png, tmp_path, capsys):
    bad = tmp_path / 'H.txt'
    bad.write_text('1 2\n')
    for extra, message in ((['--homography', str(bad)], '3 rows'),
                           (['--m-per-px', '-1'], 'positive'),
                           (['--pattern', str(tmp_path / 'x.txt')], 'needs --m-per-px'),
                           (['--m-per-px', '0.001', '--pattern', str(tmp_path / 'x.txt'), '--object', '3'],
                            'objects 0..0')):
        assert cli(['perceive', '--image', str(stroke_png), '--out', str(tmp_path / 'p.csv')] + extra) == 2
        assert message in capsys.readouterr().err


def test_deployed_shape_of_a_rod_photo_is_ready_for_evaluate(tmp_path, capsys):
    """A photo of a rod lying as a letter 'e' (crossing itself): the deployed CSV starts at the end nearest
    to --start-near, is in metres, and `rod-deploy evaluate` reads it (Eq. 17 against the true shape)."""
    import json

    from rod_deploy.deployment.metrics import read_deployed_csv
    from rod_deploy.perception.crossing_scenes import crossing_scene
    from rod_deploy.perception.path_io import write_pattern_file
    scene = crossing_scene('letter_e', 7, shape=(360, 480))
    image = tmp_path / 'rod.png'
    cv2.imwrite(str(image), scene.image)
    s = 0.001
    true_xy = np.stack([scene.curves[0][:, 1] * s, (359 - scene.curves[0][:, 0]) * s], axis=1)
    for start, far in ((true_xy[-1], true_xy[0]), (true_xy[0], true_xy[-1])):
        deployed = tmp_path / 'deployed.csv'
        assert cli(['perceive', '--image', str(image), '--m-per-px', str(s), '--out', str(tmp_path / 'p.csv'),
                    '--deployed-out', str(deployed), '--start-near', *map(str, start)]) == 0
        assert deployed.read_text().startswith('x,y\n')
        xy = read_deployed_csv(deployed)
        assert np.linalg.norm(xy[0] - start) < 0.003 and np.linalg.norm(xy[-1] - far) < 0.003
    pattern = tmp_path / 'pattern.txt'
    write_pattern_file(pattern, true_xy)
    capsys.readouterr()
    from rod_deploy.cli.main import main
    assert main(['evaluate', '--pattern', str(pattern), '--deployed', str(deployed), '--directed']) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert report['e_mean_cm'] < 0.2 and not report['reversed']     # Eq. 17 in order: under 2 px


def test_deployed_out_needs_metres_and_start_near_needs_it(stroke_png, tmp_path, capsys):
    assert cli(['perceive', '--image', str(stroke_png), '--out', str(tmp_path / 'p.csv'),
                '--deployed-out', str(tmp_path / 'd.csv')]) == 2
    assert 'error: --deployed-out needs --m-per-px' in capsys.readouterr().err
    assert cli(['perceive', '--image', str(stroke_png), '--m-per-px', '0.001', '--out', str(tmp_path / 'p.csv'),
                '--start-near', '0', '0']) == 2
    assert 'error: --start-near applies to --deployed-out' in capsys.readouterr().err
    assert not (tmp_path / 'd.csv').exists()
