"""Operating-point optimisation: search spaces, constraints, optuna studies on the
surrogate or the simulator, verification by the simulator, and closing the loop.

``pipeline.optimise.workflow.run_optimise`` ties the parts together; ``vibro optimise`` / ``vibro verify`` are the CLI.
"""
