"""`isaac fit`: values of a scene's `vary`s that meet its goals (docs/goals.md).

evaluate.py runs the scene at a point (here, or on Dask workers as a sweep's variants run), solve.py chooses and
drives the optimizer (scipy.optimize), command.py is the command line: progress, the fitted run, fit.json.
"""
