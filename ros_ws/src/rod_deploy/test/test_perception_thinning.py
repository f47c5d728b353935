"""Compiled thinning: the published conditions (Zhang-Suen with Lü and Wang's bound, Holt et al.'s staircase
removal) pixel for pixel, and the same topology as scikit-image's ``skeletonize`` on strokes."""
import cv2
import numpy as np
import pytest
from scipy.ndimage import distance_transform_edt
from skimage.measure import euler_number, label
from skimage.morphology import skeletonize

from rod_deploy.perception.skeleton_graph import skeleton_of
from rod_deploy.perception.thinning import zhang_suen_thinning


def random_masks(seed, n, kinds=(0, 1, 2)):
    """Noise of several densities, noise grown into blobs, and thick random strokes (crossings, loops)."""
    rng = np.random.default_rng(seed)
    for k in range(n):
        h, w = (int(v) for v in rng.integers(1, 48, 2))
        kind = kinds[k % len(kinds)]
        if kind == 0:
            mask = rng.random((h, w)) < rng.uniform(0.1, 0.95)
        elif kind == 1:
            mask = cv2.dilate((rng.random((h, w)) < 0.1).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
        else:
            h, w = h + 20, w + 20
            mask = np.zeros((h, w), np.uint8)
            for _ in range(int(rng.integers(1, 4))):
                pts = rng.uniform(0, [w, h], (4, 2)).astype(np.int32)
                cv2.polylines(mask, [pts], bool(rng.integers(2)), 1, int(rng.integers(2, 9)))
            mask = mask > 0
        yield mask


def reference_thinning(mask):
    """The papers' conditions written on whole images (neighbour images P2..P9), slow and direct."""
    img = np.pad(mask.astype(np.int32), 1)

    def neighbours(a):
        s = lambda dr, dc: np.roll(np.roll(a, -dr, 0), -dc, 1)     # noqa: E731 (value at (r + dr, c + dc))
        return [s(-1, 0), s(-1, 1), s(0, 1), s(1, 1), s(1, 0), s(1, -1), s(0, -1), s(-1, -1)]   # P2..P9

    def zhang_suen_step(a, first):
        p = neighbours(a)
        p2, p4, p6, p8 = p[0], p[2], p[4], p[6]
        b = sum(p)
        transitions = sum((p[i] == 0) & (p[(i + 1) % 8] == 1) for i in range(8))
        cond = (a == 1) & (b >= 3) & (b <= 6) & (transitions == 1)
        cond &= ((p2 * p4 * p6 == 0) & (p4 * p6 * p8 == 0)) if first else ((p2 * p4 * p8 == 0) & (p2 * p6 * p8 == 0))
        return np.where(cond, 0, a)

    while True:
        before = img
        img = zhang_suen_step(zhang_suen_step(img, True), False)
        if np.array_equal(img, before):
            break
    for north in (True, False):
        n, ne, e, se, s, sw, w, nw = neighbours(img)
        if not north:                      # the south pass: N <-> S, NE <-> SE, NW <-> SW
            n, ne, nw, s, se, sw = s, se, sw, n, ne, nw
        corner = n & ((e & (1 - ne) & (1 - sw) & ((1 - w) | (1 - s))) | (w & (1 - nw) & (1 - se) & ((1 - e) | (1 - s))))
        img = np.where((img == 1) & (corner == 1), 0, img)
    return img[1:-1, 1:-1].astype(bool)


@pytest.mark.parametrize('seed', [0, 1])
def test_thinning_follows_the_published_conditions_on_random_masks(seed):
    differing = [m.shape for m in random_masks(seed, 120) if not np.array_equal(zhang_suen_thinning(m),
                                                                                  reference_thinning(m))]
    assert differing == []


def test_thinning_has_skimages_topology_on_strokes():
    """Strokes (thick lines, crossings, loops): the same 8-connected pieces and holes as ``skeletonize``'s
    skeleton, within a few pixels of it (they differ mostly where the ends stop), inside the mask."""
    far = []
    for mask in random_masks(2, 90, kinds=(2,)):
        ours, theirs = zhang_suen_thinning(mask), skeletonize(mask)
        assert not (ours & ~mask).any()
        assert label(ours, connectivity=2).max() == label(theirs, connectivity=2).max()
        assert euler_number(ours, connectivity=2) == euler_number(theirs, connectivity=2)
        far.append(max(distance_transform_edt(~theirs)[ours].max(), distance_transform_edt(~ours)[theirs].max()))
    assert np.median(far) <= 3.0 and max(far) <= 10.0


def test_thin_diagonal_strokes_survive_and_come_out_one_pixel_wide():
    for flip in (False, True):
        mask = np.zeros((30, 30), bool)
        for i in range(2, 28):
            mask[i, i:i + 2] = True        # 2 px thick staircase: the paper's 2 <= B(P) deletes it whole
        mask = mask[:, ::-1] if flip else mask
        sk = zhang_suen_thinning(mask)
        assert sk.sum() >= 24
        n = cv2.filter2D(sk.astype(np.uint8), -1, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_CONSTANT) - 1
        assert n[sk].max() <= 2                # no pixel with three neighbours: no false junction
        assert label(sk, connectivity=2).max() == 1


def test_thinning_of_a_full_frame_blob_and_of_a_crop():
    mask = np.ones((120, 160), bool)       # touches every image border
    sk = zhang_suen_thinning(mask)
    assert 0 < sk.sum() < 400 and label(sk, connectivity=2).max() == 1
    ring = np.zeros((200, 240), np.uint8)
    cv2.circle(ring, (150, 90), 50, 1, 11)
    cv2.line(ring, (20, 180), (230, 20), 1, 9)
    ring = ring > 0
    sk = skeleton_of(ring)                 # thinned on the bounding box, placed back
    assert np.array_equal(sk, zhang_suen_thinning(ring))
    assert sk.sum() > 400 and euler_number(sk, connectivity=2) == euler_number(skeletonize(ring), connectivity=2)


def test_thinning_keeps_what_cannot_be_thinned_and_rejects_3d():
    assert not zhang_suen_thinning(np.zeros((5, 7), bool)).any()
    dot = np.zeros((5, 5), bool)
    dot[2, 2] = True
    assert np.array_equal(zhang_suen_thinning(dot), dot)
    line = np.zeros((7, 9), bool)
    line[3, 1:8] = True
    assert np.array_equal(zhang_suen_thinning(line), line)
    assert zhang_suen_thinning(np.zeros((0, 4), bool)).shape == (0, 4)
    with pytest.raises(ValueError, match='2-D'):
        zhang_suen_thinning(np.zeros((3, 3, 3), bool))
