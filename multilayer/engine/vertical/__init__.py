"""The implicit vertical step (docs/model.md, "The implicit vertical step"): the column
problem (:mod:`.problem`), its exact solve (:mod:`.column_solve`), the stresses of the
rheology plugins (:mod:`.stresses`, compiled: :mod:`.coefficients`), the Newton iteration
on the viscous part (:mod:`.newton`, compiled and fused per column: :mod:`.newton_kernel`,
:mod:`.sheared_columns`; its control: :mod:`.newton_control`) and the compiled forms of
the laws (:mod:`.forms`)."""
