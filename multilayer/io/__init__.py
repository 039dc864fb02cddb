"""Input and output: scenario files, CF netCDF results and checkpoints, figures, VTK export."""
