"""Model diagnosis against measured data (issue 7, ``vibro diagnose``).

features.py  measured and simulated features (harmonics of the signals, summary labels) with noise
model.py     calibratable parameters, candidate effects, parallel evaluation of the simulator
fit.py       multi-start least squares with a parallel finite-difference Jacobian, uncertainty
run.py       splitting, calibration, candidate ranking and selection for one system
report.py    residual structure, figures and report.md
driver.py    the whole dataset: every system, report.json / report.md written atomically
"""
