"""The vehicle-track dynamics model: track input, contact, equations, simulation.

The compiled kernels (model, suspension, integrate, decay, wheelset) are cached by Numba in
a folder keyed by their sources (:mod:`railsusp.vehicle.kernel_cache`).
"""

#: Revision of the force laws and equations of motion: changed with every change of the model
#: that moves forces without a change of the wagon data (a new element, a corrected sign), so
#: that run directories made with another model are simulated again
#: (:func:`railsusp.pipeline.model_identity`). The stored force reference
#: (tests/data/force_reference.npz) pins the forces of this revision.
MODEL_REVISION = "2026-11-24.2"  # .2: the friction wedges resist warp (front and rear wedge)
