"""Fake hardware (bag replay), bag tools and the arm-command bridge."""
