#!/usr/bin/env bash
# The figures of docs/calibration.md: runs the three documented studies (about half an hour of runs:
# the times are quoted in docs/calibration.md) and copies the figures `multilayer plot`
# draws into docs/figures/.  Completed runs are reused, so a rerun only plots and copies.
# From the repository root: bash docs/make_calibration_figures.sh
set -euo pipefail
cd "$(dirname "$0")/.."

python studies/twin/make_observations.py 1.0 1
multilayer calibrate studies/twin/calibration.yaml
multilayer plot results/twin
cp results/twin/plots/pairs.png "docs/figures/calibration_twin_pairs.png"
cp results/twin/plots/fit.png "docs/figures/calibration_twin_fit.png"

multilayer calibrate studies/column_collapse_runout.yaml --workers 2
multilayer plot results/column-collapse-runout
cp results/column-collapse-runout/plots/pairs.png "docs/figures/calibration_collapse_pairs.png"
cp results/column-collapse-runout/plots/fit.png "docs/figures/calibration_collapse_fit.png"

multilayer sensitivity studies/erodible_bed_sobol.yaml --workers 2
multilayer plot results/erodible-bed-sobol
cp results/erodible-bed-sobol/plots/sobol.png "docs/figures/sensitivity_erodible_bed.png"
