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
        grey = rng.integers(0, 256, (h, w)).astype(np.uint8)
        centre = rng.uniform([0, 0], [h, w]) if trial % 4 == 0 else rng.uniform([35, 35], [h - 35, w - 35])
        a = rng.uniform(0, 2 * np.pi)
        b = a + rng.uniform(0.05, np.pi)
        dirs = _perturbed_directions(np.array([np.cos(a), np.sin(a)]), np.array([np.cos(b), np.sin(b)]),
                                     np.radians(8.0))
        wa, wb = rng.uniform(1, 22, 2)
        new = _edge_contrasts(grey, centre, dirs, wa, wb)
        ref = _reference_contrasts(grey, centre, dirs, wa, wb)
        assert np.array_equal(np.array(new), np.array(ref), equal_nan=True)
        finite += int(np.isfinite(new).sum())
    assert finite > 1000          # most probe sets lie inside the image


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


def test_colour_sample_and_lookup_are_the_numpy_gathers():
    from rod_deploy.perception.crossing_order import _sample
    from rod_deploy.perception.pipeline import _lookup
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
            new = _lookup(image, pts)
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


def test_profile_maps_are_the_numpy_broadcasts():
    from rod_deploy.perception.centreline import _profile_maps
    rng = np.random.default_rng(8)
    for trial in range(50):
        n = int(rng.integers(1, 300))
        pts = rng.uniform(0, 900, (n, 2))
        a = rng.uniform(0, 2 * np.pi, n)
        normals = np.stack([np.cos(a), np.sin(a)], axis=1)
        half = rng.uniform(2, 20)
        offsets = np.arange(-half, half + 1e-9, 0.5)
        cols, rows = _profile_maps(pts, normals, offsets)
        assert np.array_equal(rows, (pts[:, 0:1] + offsets[None, :] * normals[:, 0:1]).astype(np.float32))
        assert np.array_equal(cols, (pts[:, 1:2] + offsets[None, :] * normals[:, 1:2]).astype(np.float32))


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
