"""crowdweave USD interchange: reads worlds, writes clips, libraries and baked crowds.

Holds no algorithms: it only moves data between runtime structures and USD prims.
"""
