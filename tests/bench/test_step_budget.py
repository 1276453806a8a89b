"""bench.step_budget (what limits the DOPRI5 kernel's steps on each model)."""
from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import sim
from bench.step_budget import _lean_ratios, boundary_radius, stability_function

ROOT = Path(__file__).resolve().parents[2]


def test_stability_function_is_dopri5s_and_its_real_boundary():
    """From the tableau in sim.integrator: R(z) = 1 + z + z²/2 + z³/6 + z⁴/24 + z⁵/120 + z⁶/600 (Hairer, Nørsett &
    Wanner, Solving ODEs I, §II.5: DOPRI5 is 5th order with that z⁶ term), whose stability interval on the negative
    real axis ends at -3.3066 (the real root of R(x) = 1 other than 0)."""
    R = stability_function()
    z = np.array([0.3, -1.7, -0.8 + 1.1j, 2.0j])
    expected = 1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24 + z ** 5 / 120 + z ** 6 / 600
    assert np.max(np.abs(R(z) - expected)) < 1e-13
    r = boundary_radius(R, math.pi)
    assert abs(r - 3.3065678926) < 1e-8
    assert abs(R(-r) - 1.0) < 1e-9


def test_watched_run_sees_the_kernels_steps_and_the_pendulums_cap():
    """The watched (interpreted) run accepts exactly the steps the kernel counts (the ``n_steps`` label); on the
    pendulum, whose free flight runs at its step cap (``max_step_frac`` of sim/models/pendulum.py), phase 0 is
    reported as limited by the cap; the compiled floor makes 6 right-hand-side calls per attempted step."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = subprocess.run([sys.executable, "-m", "bench.step_budget", "--models", "pendulum", "--reps", "2"],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    seen = re.search(r"pendulum default: n_steps (\d+), accepted seen (\d+)", run.stderr)
    assert seen and int(seen.group(1)) == int(seen.group(2)) > 0
    rows = {int(m.group(1)): m for m in re.finditer(
        r"\| pendulum \| default \| (\d) \| ([\d.]+) \| ([\d.]+) \| ([\d.e-]+) \| ([\d.e-]+) \| \S+ \| (\w+) \|",
        run.stdout)}
    assert set(rows) == {0, 1}
    cap = sim.get_model("pendulum").default_settings["max_step_frac"]
    assert rows[0].group(6) == "cap" and abs(float(rows[0].group(4)) - cap) < 1e-9
    assert rows[1].group(6) == "accuracy"
    n_cycles = 40 + 10                                     # the pendulum point of bench.bench_precision.POINTS
    attempts = sum((float(m.group(2)) + float(m.group(3))) * n_cycles for m in rows.values())
    floor = re.search(r"\| pendulum \| default \| (\d+) \| ([\d.]+) \| ([\d.]+) \| [\d.]+ \| (x[\d.]+|n/a) \|",
                      run.stdout)
    # the per-cycle figures are printed to 0.05 of a step: 0.05 x 50 cycles x 6 calls per phase
    assert floor and abs(int(floor.group(1)) - 6 * attempts) <= 6 * 0.05 * n_cycles * len(rows)
    assert 0.0 < float(floor.group(2)) < float(floor.group(3))        # the model alone costs less than the run


@pytest.mark.parametrize("args, needle", [
    (["--set", "c3=abc"], "--set c3=abc: expected name=number"),
    (["--set", "c3"], "--set c3: expected name=number"),
    (["--models", "pendulum", "--write-readme"], "--write-readme: only the full default run"),
    (["--models", "pendulum", "--set", "c9=1"], "pendulum: "),
    (["--models", "pendulm"], "--models pendulm: no benchmark point"),
])
def test_bad_arguments_get_one_line(args, needle):
    run = subprocess.run([sys.executable, "-m", "bench.step_budget", *args], cwd=ROOT,
                         env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True, timeout=120)
    assert run.returncode != 0
    assert needle in run.stderr and "Traceback" not in run.stderr


def test_the_floor_takes_the_dopri5_kernels_ratio_not_a_hybrids(tmp_path):
    """The floor table sets the model's right-hand side against the DOPRI5 kernel's run, so it quotes that kernel's
    lean-kernel ratio; a model with a hybrid propagator has a second lean row (bench_precision.lean_vs_old)."""
    import json

    rows = [{"model": "rimd", "point": "default", "method": "dopri5", "ratio": 1.5},
            {"model": "rimd", "point": "default", "method": "hybrid", "ratio": 2.3},
            {"model": "pendulum", "point": "default", "ratio": 2.1}]          # a run from before the method column
    path = tmp_path / "precision.json"
    path.write_text(json.dumps({"lean_vs_old": rows}))
    assert _lean_ratios(path) == {("rimd", "default"): 1.5, ("pendulum", "default"): 2.1}
    assert _lean_ratios(tmp_path / "missing.json") == {}
