"""Pattern and rod perception: a photo of drawn strokes or rods -> ordered centrelines in table metres.

``pipeline.perceive`` runs the steps (mBEST, Choi et al. 2023, plus sub-pixel refinement):
``segmentation`` (mask and evidence), ``skeleton_graph`` (Zhang-Suen skeleton as ends, junctions, chains),
``bending_energy_pairing`` (branches paired at crossings), ``traversal`` (one ordered path per object),
``crossing_order`` (over/under from colour), ``centreline`` (edge-centred, smoothed, resampled).
``pixel_mapping`` maps pixels to table metres, ``path_io`` writes path.csv and the pattern file,
``overlay`` draws the result for people, ``evaluation`` scores it (instance DICE, centreline RMS) and
``synthetic`` draws test images with known centrelines.
"""
