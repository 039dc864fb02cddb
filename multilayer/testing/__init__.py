"""Regression and reference expectations of scenario files, and their pytest plugin."""
