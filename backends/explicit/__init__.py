"""Shared numpy-only layer of the explicit backends (numba, torch)."""
