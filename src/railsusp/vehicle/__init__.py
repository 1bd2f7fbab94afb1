"""The vehicle-track dynamics model: track input, contact, equations, simulation.

The compiled kernels (the modules of :data:`railsusp.vehicle.kernel_cache.KERNEL_SOURCES`) are
cached by Numba in a folder keyed by their sources (:mod:`railsusp.vehicle.kernel_cache`).
"""

#: Revision of the force laws and equations of motion: changed with every change of the model
#: that moves forces without a change of the wagon data (a new element, a corrected sign), so
#: that run directories made with another model are simulated again
#: (:func:`railsusp.pipeline_inputs.model_identity`). The stored force reference
#: (tests/data/force_reference.npz) pins the forces of this revision.
#: 2026-11-24.2: the friction wedges resist warp (front and rear wedge); 2026-11-30.1: the
#: RK4 step within its stability bound below about 58 km/h and the irregularities' fade-in
#: ending before the record with lead-ins under 40 m (forces at 60 km/h with the 100 m
#: lead-in unchanged, bit for bit); 2026-11-30.2: the side frames roll with their wheelsets
#: (the couple of their lateral forces reaches the wheel loads), the car body's gravity roll
#: moment, the coupler line's angle halfway between like cars (docs/model.md; wagon fields
#: that restore those three: railsusp.vehicle.wagon.FORCE_LAWS_BEFORE_2026_11_30_2), the
#: rail damping's push capped at the Hertz force (no step at a touch-down) and a track grid
#: as fine as the synthesis where wavelengths go below 1 m; 2026-12-02.1: the centre bowl's
#: pitch moment acts between the car body and its bogie's side frames (it acted against the
#: track, with no reaction), the bolster's pitch restraint acts between the two side frames
#: too (on level track as on a grade: the wheel loads' s.d. moved by +6 / -4 % on leading /
#: trailing axles), and a bogie's own pitch moment on a grade is shared between its axles
#: (wagon fields that restore them: railsusp.vehicle.wagon.FORCE_LAWS_BEFORE_2026_12_02_1);
#: 2026-12-03.1: the track-following frames turn in the bodies' equations (the yaw and roll
#: accelerations of a transition, the frame's yaw and roll rates in the wheelsets' gyroscopic
#: moments) and the connections between bodies at different positions take the design twist
#: (the primary's deflections, the centre plate's lateral one; docs/model.md, "Transitions";
#: tangent forces unchanged, to 2e-13; wagon fields that restore them:
#: railsusp.vehicle.wagon.FORCE_LAWS_BEFORE_2026_12_03_1); 2026-12-03.2: the side frames'
#: yaw moves the cross-bracing pins (X10 / 2 - b2 outboard of their centrelines) and the axle
#: boxes (b1 - b2; zero for the K6) longitudinally, so that a rigid yaw of the bogie strains
#: no bar (it stretched one and shortened the other, 1.7 kN each at 5 mrad; docs/model.md;
#: wagon fields that restore it: railsusp.vehicle.wagon.FORCE_LAWS_BEFORE_2026_12_03_2)
MODEL_REVISION = "2026-12-03.2"
