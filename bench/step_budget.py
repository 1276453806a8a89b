"""Step budget of the DOPRI5 kernel: per model and phase, how many steps a forcing cycle takes and
what limits their size -- the error control (accuracy), the step cap (``max_step_frac``), or stability.

Runs every benchmark point (``bench.bench_precision.POINTS``, its fixed transient and window) at the default rtol with
the kernel *interpreted* (numba disabled, so the kernel's calls can be watched; the step sequence is the compiled
kernel's, which ``tests/bench/test_step_budget.py`` checks against the ``n_steps`` label).  Each attempted step is
seen at its first two stage evaluations (k2 at t + h/5, k3 at t + 3h/10: they give t and h); an attempt is
accepted when the kernel then evaluates the guards (only an accepted step looks for switches).  For every accepted step of the last cycle the model's Jacobian is
taken by central differences of its right-hand side at the step's k2 stage state (same phase and discrete
state); the stability limit of that step is ``min over eigenvalues λ (Re λ <= 0) of r(arg λ) / |λ|``, with
``r(φ)`` the radius where DOPRI5's stability function ``R(z) = 1 + z b^T (I - zA)^-1 1`` (from the tableau in
``sim.integrator``) first reaches ``|R| = 1`` along the ray ``arg z = φ`` (3.31 on the negative real axis).

Then, compiled, the **right-hand side alone**: 6 calls of the model's ``rhs`` per attempted step (DOPRI5's stages
k2 ... k7), each phase's at a state of that phase, timed against the whole run (minima of interleaved repetitions):
what any DOPRI5 kernel taking these steps spends in the model's arithmetic.  With the lean-kernel ratio of the last
``bench_precision`` run (``results/precision.json``) it gives the share of today's remaining time (everything but the
right-hand side) that a ×2 over the old kernel would leave.

A phase is reported as limited by the **cap** when its median accepted step is within 2 % of ``max_step_frac`` T, by
**stability** when it is at least half the median stability limit (an error-controlled explicit method settles just
under its stability limit, rejecting a step now and then), else by **accuracy**.

Run: ``python -m bench.step_budget [--models pendulum,...] [--set name=value ...] [--no-floor] [--write-readme]``
(``--set c3=100`` e.g. shows the indenters without their stiff piston mode).  Not a test: nothing asserts a timing.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

K2_ROW, K3_ROW = 1, 2          # rows of the kernel's workspace holding the stages k2, k3 (sim/_kernel_template.py)
CAP_CLOSE = 0.98               # median step >= this x cap: limited by the cap
STAB_CLOSE = 0.5               # median step >= this x median stability limit: limited by stability
START, END = "<!-- step-budget:start -->", "<!-- step-budget:end -->"


def stability_function():
    """DOPRI5's stability function R(z) (the 5th-order solution of sim.integrator's tableau), vectorised in z."""
    from sim.integrator import dopri5_tableau
    a, b, _, _ = dopri5_tableau()
    # explicit: (I - zA)^-1 1 = sum_k (zA)^k 1, a polynomial of degree 6
    coef = [1.0]
    v = np.ones(7)
    for _ in range(7):
        coef.append(float(b @ v))
        v = a @ v
    coef = np.array(coef)                       # R(z) = 1 + sum_k coef[k] z^k, k >= 1

    def R(z):
        z = np.asarray(z, dtype=complex)
        return np.polyval(coef[::-1], z)
    return R


def boundary_radius(R, phi: float, r_max: float = 10.0) -> float:
    """Smallest r > 0 with |R(r e^{iφ})| = 1 (scanned, then bisected); r_max if none below it."""
    rs = np.linspace(1e-3, r_max, 4000)
    m = np.abs(R(rs * np.exp(1j * phi))) > 1.0
    if not m.any():
        return r_max
    k = int(np.argmax(m))
    lo, hi = (rs[k - 1] if k > 0 else 0.0), rs[k]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if abs(R(mid * np.exp(1j * phi))) > 1.0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def _jacobian(rhs, t, y, z, ph, p, scale):
    n = y.shape[0]
    jac = np.empty((n, n))
    fp, fm = np.empty(n), np.empty(n)
    for j in range(n):
        d = 1e-7 * max(abs(y[j]), scale[j])
        yp, ym = y.copy(), y.copy()
        yp[j] += d
        ym[j] -= d
        rhs(t, yp, z.copy(), ph, p, fp)
        rhs(t, ym, z.copy(), ph, p, fm)
        jac[:, j] = (fp - fm) / (2.0 * d)
    return jac


def watch(model: str, preset, settings: dict, overrides: dict | None = None) -> dict:
    """Run one point with the interpreted kernel, watching its stage calls.  Returns the attempts
    (t, h, phase, accepted, stability-limited step or nan), the period, the cap, the labels and the cycle count."""
    import sim
    import sim.compiled as C
    from sim.jit import interpreted

    spec = sim.get_model(model)
    run_point = C.kernels(spec.funcs, spec.n_bounded, None)
    mod = sys.modules[run_point.__module__]
    model_rhs = interpreted(spec.funcs[0])
    ws = {}
    calls = []               # [t of the k2 call, t of the k3 call, phase, stage-2 state, z, accepted]
    orig_ws, orig_rhs, orig_guards = mod.make_workspace, mod.rhs, mod.guards

    def make_workspace(*a):
        wk, gk = orig_ws(*a)
        ws["k2"], ws["k3"] = wk[K2_ROW].ctypes.data, wk[K3_ROW].ctypes.data
        ws["p"] = a[0]                          # make_workspace(p, period, s, ny): the run's parameter vector
        return wk, gk

    def rhs(t, y, z, ph, p, dy):
        ptr = dy.ctypes.data
        if ptr == ws.get("k2"):
            calls.append([t, None, ph, y.copy(), z.copy(), False])
        elif ptr == ws.get("k3") and calls and calls[-1][1] is None:
            calls[-1][1] = t
        return orig_rhs(t, y, z, ph, p, dy)

    def guards(t, y, z, ph, p, g):
        if calls:              # only an accepted step looks for switches: a rejected one goes straight to its retry
            calls[-1][5] = True
        return orig_guards(t, y, z, ph, p, g)

    mod.make_workspace, mod.rhs, mod.guards = make_workspace, rhs, guards
    try:
        res = sim.simulate(model, preset=preset, settings=settings, **(overrides or {}))
    finally:
        mod.make_workspace, mod.rhs, mod.guards = orig_ws, orig_rhs, orig_guards
    period = 1.0 / res.params["frequency_hz"]
    import sim.integrator as I
    p = ws["p"]
    rows = []                                   # [t, h, phase, stage-2 state, z] of every attempt
    for t2, t3, ph, y2, z, _ in calls:
        h = (t3 - t2) / (I.C3 - I.C2)
        rows.append([t2 - I.C2 * h, h, ph, y2, z])
    accepted = [c[5] for c in calls]
    cap = res.settings.max_step_frac * period
    n_cycles = settings["max_transient"] + settings["window"]
    # stability limit of the accepted steps of the last cycle
    R = stability_function()
    radius = {}
    t_last = max(r[0] for r in rows) - period
    scale = np.abs(res.final_state[0]) + 1e-12
    h_stab = []
    states = {}                                 # per phase: the k2 stage state of its last accepted step
    for (t, h, ph, y2, z), ok in zip(rows, accepted):
        if ok:
            states[int(ph)] = (t + I.C2 * h, y2.tolist(), z.tolist())
        if not ok or t < t_last:
            h_stab.append(math.nan)
            continue
        lam = np.linalg.eigvals(_jacobian(model_rhs, t + I.C2 * h, y2, z, ph, p, scale))
        lim = math.inf
        for lm in lam:
            if abs(lm) < 1e-9 / period or lm.real > 0.0:
                continue
            phi = round(float(np.angle(lm)), 3)
            if phi not in radius:
                radius[phi] = boundary_radius(R, phi)
            lim = min(lim, radius[phi] / abs(lm))
        h_stab.append(lim)
    return {"model": model, "t": np.array([r[0] for r in rows]), "h": np.array([r[1] for r in rows]),
            "phase": np.array([r[2] for r in rows]), "accepted": np.array(accepted), "h_stab": np.array(h_stab),
            "period": period, "cap": cap, "labels": res.labels, "n_cycles": n_cycles, "states": states,
            "p": p.tolist()}


def budget(w: dict) -> list[dict]:
    """Per phase: attempts and rejections per cycle, median accepted h / T, cap / T, median stability limit / T
    (last cycle), and what limits the step."""
    out = []
    T, nc = w["period"], w["n_cycles"]
    for ph in sorted(set(int(x) for x in w["phase"])):
        sel = w["phase"] == ph
        acc = sel & w["accepted"]
        h_med = float(np.median(w["h"][acc])) if acc.any() else math.nan
        hs = w["h_stab"][acc]
        hs = hs[np.isfinite(hs)]
        stab = float(np.median(hs)) if hs.size else math.inf
        if h_med >= CAP_CLOSE * w["cap"]:
            limit = "cap"
        elif math.isfinite(stab) and h_med >= STAB_CLOSE * stab:
            limit = "stability"
        else:
            limit = "accuracy"
        out.append({"phase": ph, "attempts": int(sel.sum()), "attempts_per_cycle": float(sel.sum()) / nc,
                    "rejected_per_cycle": float((sel & ~w["accepted"]).sum()) / nc,
                    "h_over_T": h_med / T, "cap_over_T": w["cap"] / T, "stab_over_T": stab / T, "limit": limit})
    return out


def table(points: list[dict], command: str) -> str:
    """The step-budget table of ``points`` (``watch_all``'s records: model, point, per-phase rows)."""
    lines = [f"Generated by `{command}` (kernel interpreted, rtol 1e-7, the benchmark's transient and window; "
             "h: median accepted step, cap: max_step_frac T, stability: median over the last cycle's accepted steps of "
             "DOPRI5's stability limit on the model's Jacobian).", "",
             "| model | point | phase | steps / cycle | rejected / cycle | h / T | cap / T | stability / T | limited by |",
             "|---|---|---|---|---|---|---|---|---|"]
    for pt in points:
        model, pid = pt["model"], pt["point"]
        for r in pt["rows"]:
            stab = f"{r['stab_over_T']:.3g}" if math.isfinite(r["stab_over_T"]) else "none"
            lines.append(f"| {model} | {pid} | {r['phase']} | {r['attempts_per_cycle'] - r['rejected_per_cycle']:.1f} | "
                         f"{r['rejected_per_cycle']:.1f} | {r['h_over_T']:.3g} | {r['cap_over_T']:.3g} | {stab} | "
                         f"{r['limit']} |")
    return "\n".join(lines)


def _overrides(items: list[str]) -> dict:
    out = {}
    for it in items:
        name, _, val = it.partition("=")
        try:
            out[name] = float(val)              # also refuses a missing "=" (float(""))
        except ValueError:
            raise SystemExit(f"--set {it}: expected name=number") from None
    return out


def interpret_kernels() -> None:
    """Make the kernels run as Python from here on (numba disabled, no ahead-of-time module), so ``watch`` sees
    their calls; only possible before numba is imported."""
    if "numba" in sys.modules and os.environ.get("NUMBA_DISABLE_JIT") != "1":
        raise SystemExit("bench.step_budget: numba is already imported; run it as `python -m bench.step_budget`")
    os.environ["NUMBA_DISABLE_JIT"] = "1"
    os.environ["VIBRO_NO_AOT"] = "1"


def _points(models: list[str]):
    from bench.bench_precision import DEFAULT_RTOL, POINTS
    for model, pid, preset, n, w in POINTS:
        if not models or model in models:
            yield model, pid, preset, {"min_transient": n, "max_transient": n, "window": w, "rtol": DEFAULT_RTOL,
                                       "method": "dopri5"}


def watch_all(models: list[str], over: dict) -> list[dict]:
    """``watch`` + ``budget`` on every point (interpreted kernels: call ``interpret_kernels`` first)."""
    from sim.models.base import ParameterError

    out = []
    for model, pid, preset, st in _points(models):
        try:
            wt = watch(model, preset, st, over)
        except ParameterError as e:
            raise SystemExit(f"bench.step_budget: {model}: {e}") from None
        out.append({"model": model, "point": pid, "preset": preset, "settings": st, "rows": budget(wt),
                    "n_steps": int(wt["labels"]["n_steps"]), "accepted_seen": int(wt["accepted"].sum()),
                    "states": {str(k): v for k, v in wt["states"].items()}, "p": wt["p"]})
        print(f"{model} {pid}: n_steps {out[-1]['n_steps']}, accepted seen {out[-1]['accepted_seen']}",
              file=sys.stderr)
    return out


def rhs_floor(points: list[dict], over: dict, reps: int = 30) -> list[dict]:
    """Compiled: per point, the CPU of 6 right-hand-side calls per attempted step (DOPRI5's stages k2..k7, each
    phase's calls at that phase's state, t advancing) against the CPU of the whole run, minima of ``reps``
    interleaved repetitions.  The floor is what any DOPRI5 kernel taking these steps spends in the model alone."""
    import time

    from numba import njit

    import sim

    out = []
    for pt in points:
        spec = sim.get_model(pt["model"])
        # the model's right-hand side inlined into the timing loop, as the kernel inlines it (sim.compiled); calling
        # its cached dispatcher instead gave timings that changed from one recompile to the next
        rhs = njit(inline="always")(spec.funcs[0].py_func)

        @njit
        def loop(p, n, ph, t0, dt, y0, z0, rhs=rhs):
            y = y0.copy()
            z = z0.copy()
            dy = np.empty_like(y)
            acc = 0.0
            for i in range(n):
                rhs(t0 + dt * i, y, z, ph, p, dy)
                acc += dy[0]
            return acc

        p = np.array(pt["p"])
        calls = [(int(r["phase"]), 6 * r["attempts"]) for r in pt["rows"]]
        period = 1.0 / spec.resolve(pt["preset"], **over)["frequency_hz"]
        args = []
        for ph, n in calls:
            t, y, z = pt["states"][str(ph)]
            args.append((p, n, ph, t, period / max(n, 1), np.array(y), np.array(z, dtype=float)))

        def floor():
            for a in args:
                loop(*a)

        def whole():
            sim.simulate(pt["model"], preset=pt["preset"], settings=pt["settings"], **over)
        floor()
        whole()
        tf, tw = [], []
        for _ in range(reps):
            for fn, acc in ((floor, tf), (whole, tw)):
                c = time.process_time()
                fn()
                acc.append(time.process_time() - c)
        out.append({"model": pt["model"], "point": pt["point"], "rhs_calls": sum(n for _, n in calls),
                    "floor_s": min(tf), "run_s": min(tw)})
    return out


def floor_table(floors: list[dict], lean: dict) -> str:
    """The floor against the run and, with the benchmark's old/current ratio ``lean`` (results/precision.json),
    the share of today's non-rhs time a ×2 over the old kernel would leave."""
    lines = ["| model | point | rhs calls | rhs calls alone, ms | whole run, ms | rhs share | old / current "
             "(precision.json) | x2 leaves the rest of the step |", "|---|---|---|---|---|---|---|---|"]
    for f in floors:
        r = lean.get((f["model"], f["point"]))
        rest = f["run_s"] - f["floor_s"]
        if r is None:
            need, rtxt = "n/a", "n/a"
        else:
            target = f["run_s"] * r / 2.0 - f["floor_s"]          # CPU the rest may take for old / 2
            need = f"{100.0 * target / rest:.0f} % of today's" if target > 0 else "nothing (the rhs alone is over)"
            rtxt = f"x{r:.2f}"
        lines.append(f"| {f['model']} | {f['point']} | {f['rhs_calls']} | {f['floor_s'] * 1e3:.2f} | "
                     f"{f['run_s'] * 1e3:.2f} | {f['floor_s'] / f['run_s']:.2f} | {rtxt} | {need} |")
    return "\n".join(lines)


def _lean_ratios(path: Path = ROOT / "bench" / "results" / "precision.json") -> dict:
    """(model, point) -> the last bench_precision run's old / current ratio of the DOPRI5 kernel ({} without a run)."""
    import json
    try:
        res = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return {(x["model"], x["point"]): x["ratio"] for x in res.get("lean_vs_old", [])
            if x.get("method", "dopri5") == "dopri5"}       # the DOPRI5 kernel's row (a hybrid has its own)


def main(argv: list[str] | None = None) -> int:
    import json
    import subprocess
    import tempfile

    ap = argparse.ArgumentParser(prog="python -m bench.step_budget", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="examples:\n  python -m bench.step_budget --write-readme\n"
                                        "  python -m bench.step_budget --models indenter-metal --set c3=100\n"
                                        "  python -m bench.step_budget --models pendulum --no-floor")
    ap.add_argument("--models", default="", help="comma-separated models (default: every benchmark point)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="parameter override for every point (MODELS.md symbol)")
    ap.add_argument("--no-floor", action="store_true", help="skip the compiled right-hand-side floor timing")
    ap.add_argument("--reps", type=int, default=30, help="repetitions of the floor timing (default 30)")
    ap.add_argument("--write-readme", action="store_true", help="write the tables into bench/README.md's markers")
    ap.add_argument("--watch-json", metavar="PATH", help=argparse.SUPPRESS)   # child: interpreted watch -> JSON
    a = ap.parse_args(argv)
    models = [m for m in a.models.split(",") if m]
    from bench.bench_precision import POINTS
    known = sorted({pt[0] for pt in POINTS})
    for m in models:
        if m not in known:
            raise SystemExit(f"--models {m}: no benchmark point of that model; known: {', '.join(known)}")
    over = _overrides(a.set)
    if a.watch_json:
        interpret_kernels()
        Path(a.watch_json).write_text(json.dumps(watch_all(models, over)))
        return 0
    if a.write_readme and (over or models or a.no_floor):
        raise SystemExit("--write-readme: only the full default run goes into bench/README.md")
    # the watch runs interpreted, in a child process (numba cannot be switched off once imported)
    with tempfile.TemporaryDirectory() as tmp:
        js = Path(tmp) / "watch.json"
        cmd = [sys.executable, "-m", "bench.step_budget", "--watch-json", str(js)] + \
            (["--models", a.models] if a.models else []) + [x for s_ in a.set for x in ("--set", s_)]
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
        if subprocess.run(cmd, cwd=ROOT, env=env).returncode != 0:
            return 1
        points = json.loads(js.read_text())
    command = "python -m bench.step_budget" + "".join(f" --set {s_}" for s_ in a.set) + \
        (f" --models {a.models}" if a.models else "")
    text = table(points, command)
    if not a.no_floor:
        floors = rhs_floor(points, over, a.reps)
        text += ("\n\n**Right-hand side alone** (compiled; 6 calls per attempted step above, each phase's at a state "
                 f"of that phase; minima of {a.reps} interleaved repetitions against the whole run's; the old / current "
                 "ratio is the last `bench_precision` run's lean-kernel row):\n\n" + floor_table(floors, _lean_ratios()))
    print(text)
    if a.write_readme:
        from bench import write_block

        write_block(ROOT / "bench" / "README.md", START, END, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
