"""The application layer: the command line, the runner of a scenario into an output
directory, the progress line and parameter sweeps on Dask."""
