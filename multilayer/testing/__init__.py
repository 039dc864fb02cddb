"""The pytest plugin of the ``expect:`` lists of scenario files (the checks themselves:
:mod:`multilayer.app.expectations`)."""
