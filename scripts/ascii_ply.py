"""Writing a point cloud as ascii PLY, for the scene scripts beside this file."""


def write(path, points):
    """Writes `points` (an n x 3 NumPy array) to `path` as ascii PLY, 5 decimals."""
    import numpy as np

    with open(path, "w") as f:
        f.write("ply\nformat ascii 1.0\nelement vertex %d\n" % len(points))
        f.write("property float x\nproperty float y\nproperty float z\nend_header\n")
        np.savetxt(f, points, fmt="%.5f")
