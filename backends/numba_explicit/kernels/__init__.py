"""Numba kernels of the explicit solver, one concept per file.

They are concatenated (in ``codegen.KERNEL_FILES`` order, without their ``# >>> standalone``
blocks) with a material's generated code into one cached module per material; each file is also
importable on its own (with stub material functions) for tests and reading. Importing this
package does not import numba.
"""
