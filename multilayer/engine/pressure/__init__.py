"""The pressure in the yield stresses and the projection of the velocities (docs/nonhydrostatic.md)."""
