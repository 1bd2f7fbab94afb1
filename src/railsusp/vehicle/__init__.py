"""The vehicle-track dynamics model: track input, contact, equations, simulation.

The compiled kernels (model, suspension, integrate, decay, wheelset) are cached by Numba in
a folder keyed by their sources (:mod:`railsusp.vehicle.kernel_cache`).
"""
