"""Data files shipped with the planner (the sample outposts)."""
