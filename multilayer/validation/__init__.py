"""Validation of the model against exact solutions and published results.

One module per case in :mod:`multilayer.validation.cases` runs shipped scenarios (with
``--set`` overrides), measures the runs and judges them against their references; the
thresholds of the criteria are defined there once.  ``tests/test_validation.py`` asserts
the criteria that are met, and the report renderer writes docs/validation.md from the
same functions::

    python -m multilayer.validation dambreak        # one case, into ./validation.md
    python docs/make_validation.py -j 2             # the documentation's report

Reference and experimental data the cases read are in ``multilayer/validation/data/``,
each file with its source.  The engine never imports this package.
"""
