"""Geometry for parallel-jaw grasping: meshes, facets, grasp candidates, collision, quality.

This package knows nothing of the knowledge base: arrays and meshes in, arrays out.
"""
