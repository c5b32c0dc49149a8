"""Paper studies built on the gmwm library (simulations, real-data analyses, report tables).

The core package :mod:`gmwm` never imports this package; the Snakemake workflow does.
"""
