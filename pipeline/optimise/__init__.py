"""Operating-point optimisation: search spaces, constraints, optuna studies on the surrogate or the simulator,
verification by the simulator.

``outcome.optimise`` is the workflow (config in, the study, its feedback, the fallback to the simulator and the report
written, an ``OptimiseOutcome`` out); ``workflow.plan_optimise`` / ``workflow.run_optimise`` are its driver (config and
strategies in, an ``OptimiseResult`` out); ``outputs.py`` writes its report; ``vibro optimise`` / ``vibro verify`` are
the CLI.
"""
