"""Skeleton graph: ends, junctions, chains, spur and pinhole-loop pruning, closed loops."""
import cv2
import numpy as np

from rod_deploy.perception.skeleton_graph import (END, JUNCTION, Node, SkeletonGraph, build_skeleton_graph,
                                                  dissolve_pass_through_junctions, prune_spurs, remove_small_parts,
                                                  skeleton_of)


def kinds(graph):
    return sorted(n.kind for _, n in graph.live_nodes())


def test_a_line_is_one_edge_between_two_ends_in_order():
    mask = np.zeros((60, 200), bool)
    cv2.line(mask.view(np.uint8), (20, 30), (180, 30), 1, 7)
    g = build_skeleton_graph(skeleton_of(mask))
    assert kinds(g) == [END, END]
    (_, e), = g.live_edges()
    assert np.all(np.diff(e.points[:, 1]) * np.sign(e.points[-1, 1] - e.points[0, 1]) > 0)   # ordered
    assert abs(e.length_px() - 160) < 12


def test_a_plus_has_one_four_way_junction():
    mask = np.zeros((200, 200), np.uint8)
    cv2.line(mask, (20, 100), (180, 100), 1, 7)
    cv2.line(mask, (100, 20), (100, 180), 1, 7)
    g = build_skeleton_graph(skeleton_of(mask > 0))
    prune_spurs(g, 8)
    junctions = [n for _, n in g.live_nodes() if n.kind == JUNCTION]
    assert len(junctions) == 1 and len(junctions[0].edges) == 4
    assert np.allclose(junctions[0].position, [100, 100], atol=2)


def test_short_spur_is_pruned_and_the_chain_rejoined():
    mask = np.zeros((100, 300), np.uint8)
    cv2.line(mask, (20, 50), (280, 50), 1, 9)
    cv2.line(mask, (150, 50), (150, 40), 1, 3)            # a bump on the boundary: a 13 px spur
    mask[36:40, 148:153] = 1
    g = build_skeleton_graph(skeleton_of(mask > 0))
    assert len(g.live_edges()) == 3
    prune_spurs(g, 16)
    assert kinds(g) == [END, END]
    assert len(g.live_edges()) == 1


def test_a_ring_is_one_closed_edge_and_specks_go():
    mask = np.zeros((200, 200), np.uint8)
    cv2.circle(mask, (100, 100), 60, 1, 6)
    mask[10:13, 10:13] = 1
    g = build_skeleton_graph(skeleton_of(mask > 0))
    remove_small_parts(g, 20)
    dissolve_pass_through_junctions(g)
    (_, e), = g.live_edges()
    assert e.closed and abs(e.length_px() - 2 * np.pi * 60) < 0.08 * 2 * np.pi * 60   # pixel steps: ~5 % long


def test_empty_skeleton():
    g = build_skeleton_graph(np.zeros((10, 10), bool))
    assert g.live_edges() == [] and g.live_nodes() == []


def test_pinhole_loop_at_a_junction_is_pruned():
    # a T of three chains plus a 6 px loop from the junction back to itself (the skeleton around a speck
    # of background caught where two rods meet): the loop goes, the T stays
    g = SkeletonGraph([], [], (100, 100))
    g.nodes += [Node(JUNCTION, np.array([50.0, 50.0])), Node(END, np.array([50.0, 0.0])),
                Node(END, np.array([50.0, 99.0])), Node(END, np.array([99.0, 50.0]))]
    for end, pts in ((1, np.stack([np.full(51, 50.0), np.arange(50.0, -1, -1)], axis=1)),
                     (2, np.stack([np.full(50, 50.0), np.arange(50.0, 100)], axis=1)),
                     (3, np.stack([np.arange(50.0, 100), np.full(50, 50.0)], axis=1))):
        g.add_edge(pts, 0, end)
    g.add_edge(np.array([[50, 50], [49, 49], [48, 50], [48, 51], [49, 52], [50, 51], [50, 50]], float), 0, 0)
    prune_spurs(g, 8)
    assert all(e.u != e.v for _, e in g.live_edges())
    assert len(g.live_edges()) == 3 and len(g.nodes[0].edges) == 3 and g.nodes[0].kind == JUNCTION
