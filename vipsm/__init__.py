"""The VIPSM estimator: pure numpy/OpenCV, no I/O, no clock; deterministic for the same inputs."""
