"""Numba kernels: rotations, rigid-body dynamics, integration methods and scenes."""
