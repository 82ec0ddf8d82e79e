"""Data shipped inside the package: default bodies, the pose library, joint-name maps."""
