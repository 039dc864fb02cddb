"""Grain–fluid mixtures with dilatancy (Bouchut, Fernández-Nieto, Mangeney & Narbona-Reina
2016, J. Fluid Mech. 801; Pailha & Pouliquen 2009, J. Fluid Mech. 633).

A granular layer saturated by a viscous fluid has a solid volume fraction ``phi`` that
changes as it is sheared: denser than its critical state it dilates, sucks fluid in and is
held by a negative excess pore pressure; looser it contracts, expels fluid and is unloaded.

- :mod:`~multilayer.engine.mixture.closure`: the material and the dilatancy closure
  (effective pressure, excess pore pressure, dilatancy angle, drag, basal stress);
- :mod:`~multilayer.engine.mixture.uniform_layer`: the uniform immersed layer on a tilted
  plane (Pailha, Nicolas & Pouliquen 2008), its implicit time step, energy and rest test.

The model is stated in docs/mixture.md.
"""
