"""Model diagnosis against measured data (``vibro diagnose``).

features.py  measured and simulated features (harmonics of the signals, summary labels) with noise
instrument.py what the recording chain (filter, delay, clock) does to the model's harmonic features
nuisance.py  an undeclared recording chain estimated beside the calibration and held fixed
model.py     calibratable parameters, candidate effects, parallel evaluation of the simulator
fit.py       multi-start least squares with a parallel finite-difference Jacobian, uncertainty
calibrate.py the base and candidate fits of every fold, stage by stage as batches of tasks on an executor
config.py    bounds of the settings, checked by DiagnoseConfig when built
run.py       splitting, calibration, candidate ranking and selection for one system (a SystemDiagnosis)
rigout.py    the corrected rig of one system's diagnosis
report.py    residual structure, figures and report.md
result.py    the typed results: SystemDiagnosis, SimulatedRuns, DiagnoseResult
report_types.py report.json as frozen records (SystemReport, DiagnoseReport), its only to_json/from_json
workflow.py  the whole dataset: every system diagnosed into a DiagnoseResult; writes nothing
outputs.py   rig files, figures, report.json and report.md of a DiagnoseResult, written atomically
cost.py      where the time goes: simulations, CPU and wall seconds per stage (report.json 'cost')
"""
