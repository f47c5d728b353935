"""Pixel-to-table mapping (CONTRACTS.md section 4) and the path.csv / pattern text files."""
import numpy as np
import pytest

from rod_deploy.perception.path_io import (PathFileError, read_path_csv, read_pattern_file, write_path_csv,
                                           write_pattern_file)
from rod_deploy.perception.pixel_mapping import (Homography, MappingError, ScaleOrigin, default_origin,
                                                 load_homography)


def test_scale_and_origin_follow_the_contract():
    m = ScaleOrigin(0.002, origin_row=100.0, origin_col=10.0)
    x, y = m.to_table(np.array([100.0, 0.0]), np.array([10.0, 60.0]))
    assert np.allclose(x, [0.0, 0.1]) and np.allclose(y, [0.0, 0.2])     # x right, y up the image
    r, c = m.to_pixels(x, y)
    assert np.allclose(r, [100, 0]) and np.allclose(c, [10, 60])
    assert default_origin((480, 640)) == (479.0, 0.0)
    with pytest.raises(MappingError):
        ScaleOrigin(0.0, 0, 0)


def test_homography_equals_scale_origin_when_it_is_one(tmp_path):
    s, r0, c0 = 0.001, 300.0, 20.0
    H = np.array([[s, 0, -s * c0], [0, -s, s * r0], [0, 0, 1]])
    f = tmp_path / 'H.txt'
    f.write_text('# table from image\n' + '\n'.join(' '.join(f'{v:.9g}' for v in row) for row in H) + '\n')
    hom = load_homography(f)
    rows, cols = np.array([0.0, 150.0, 299.0]), np.array([0.0, 320.0, 639.0])
    assert np.allclose(hom.to_table(rows, cols), ScaleOrigin(s, r0, c0).to_table(rows, cols))
    assert np.allclose(hom.to_pixels(*hom.to_table(rows, cols)), (rows, cols))
    hom.check_image((300, 640))


def test_bad_homographies_are_refused(tmp_path):
    f = tmp_path / 'H.txt'
    f.write_text('1 0 0\n0 1 0\n')
    with pytest.raises(MappingError, match='3 rows'):
        load_homography(f)
    with pytest.raises(MappingError, match='singular'):
        Homography(np.zeros((3, 3)))
    horizon = Homography(np.array([[1.0, 0, 0], [0, 1, 0], [0.01, 0, -1]]))     # w = 0 at col 100
    with pytest.raises(MappingError, match='infinity'):
        horizon.check_image((50, 200))
    with pytest.raises(MappingError, match='cannot read'):
        load_homography(tmp_path / 'missing.txt')


def test_path_csv_round_trip(tmp_path):
    px = [np.array([[1.0, 2.0], [3.5, 4.25]]), np.array([[10.0, 20.0], [11.0, 21.0], [12.0, 22.0]])]
    xy = [p * 0.001 for p in px]
    f = tmp_path / 'path.csv'
    write_path_csv(f, px, xy)
    assert f.read_text().splitlines()[0] == 'object,row,col,x,y'
    back = read_path_csv(f)
    assert list(back) == [0, 1]
    for k in (0, 1):
        assert np.allclose(back[k][0], px[k], atol=1e-3) and np.allclose(back[k][1], xy[k], atol=1e-6)
    (tmp_path / 'bad.csv').write_text('a,b\n1,2\n')
    with pytest.raises(PathFileError, match='header'):
        read_path_csv(tmp_path / 'bad.csv')


def test_pattern_file_round_trip(tmp_path):
    xy = np.array([[0.0, 0.0], [0.01, 0.002], [0.02, 0.001]])
    f = tmp_path / 'pattern.txt'
    write_pattern_file(f, xy)
    pts = read_pattern_file(f)
    assert pts.shape == (3, 3) and np.allclose(pts[:, :2], xy) and np.all(pts[:, 2] == 0)
    (tmp_path / 'two.txt').write_text('# x y\n0 0\n1 2\n')
    assert read_pattern_file(tmp_path / 'two.txt').shape == (2, 3)
