"""Deployment planning (scaling analysis, the suspended-rod BVP, the optimal grasp of paper Alg. 1-3, the dataset
sweep, and the planners built on them)."""
