"""Analysis of plans: method comparison, equilibrium certificates, golden results.

No module here imports matplotlib: the comparison's figure is :mod:`staghunt.plots.compare`.
"""
