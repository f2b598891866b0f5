"""Analysis of plans: method comparison, equilibrium certificates, golden results.

No module here but :mod:`staghunt.analysis.compare_plots` imports matplotlib.
"""
