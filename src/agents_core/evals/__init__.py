"""Evaluations: a world, a recipe, seeded episodes and a success rule; their results, statistics and reports."""
