"""Operating-point optimisation: search spaces, constraints, optuna studies on the surrogate or the simulator,
verification by the simulator.

``workflow.plan_optimise`` / ``workflow.run_optimise`` are the driver (config and strategies in, an
``OptimiseResult`` out); ``outputs.py`` writes its report; ``vibro optimise`` / ``vibro verify`` are the CLI.
"""
