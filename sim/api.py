"""Public simulation API: ``simulate`` one point, ``simulate_batch`` many in parallel."""
from __future__ import annotations

import math
import os
import threading
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from sim import layout as I
from sim.compiled import kernels
from sim.compile_notice import announce_compile
from vibrobase.errors import did_you_mean
from sim.invariants import violation
from sim.models.base import ModelSpec, ParameterError
from sim.models.discrepancy import any_on, run_cycles
from sim.registry import get_model
from vibrobase.statuses import BOUNDED_STATUSES

if TYPE_CHECKING:                  # pandas is imported only where a table is built (history, batch)
    import pandas as pd

KERNEL_LABELS = ("rop_m_s", "peak_force_n", "mean_peak_force_n", "impacts_per_cycle", "period", "peak_decel_g",
                 "energy_per_cycle_j", "specific_energy_j_m")
"""Numeric labels of MODELS.md §5 the kernel computes (plus ``status`` and ``reason``)."""

LABELS = KERNEL_LABELS + ("power_w",)
"""Every numeric label: the kernel's plus ``power_w``, the excitation's mean power [W] =
energy_per_cycle_j × frequency_hz (null where the energy is null)."""

DIAGNOSTICS = ("transient_cycles", "n_steps", "n_events")

STATUS_NAMES = {I.STATUS_OK: "ok", I.STATUS_APERIODIC: "aperiodic", I.STATUS_NO_CONTACT: "no_contact",
                I.STATUS_RUNAWAY: "runaway", I.STATUS_NOT_SETTLED: "not_settled", I.STATUS_FAILED: "failed"}
REASONS = {
    I.REASON_NONE: "",
    I.REASON_STEP_UNDERFLOW: "step size underflow (the integrator could not advance)",
    I.REASON_TOO_MANY_STEPS: "too many steps in one forcing cycle (chattering or unresolved contact)",
    I.REASON_NONFINITE: "non-finite state (the solution blew up)",
    I.REASON_DRIFT: "centre of mass accelerates every cycle: no bounded steady state",
    I.REASON_PRECHECK: "pre-check: static force exceeds the progression threshold",
    I.REASON_NOT_PERIODIC: "no period <= 8 found and the two half-windows disagree: still transient at the cap",
    I.REASON_LOST_PERIOD: "the transient repeated with a period, but the window shows none and its two halves "
                          "disagree: still drifting",
    I.REASON_WORK_LIMIT: "work limit: more integration steps than the setting max_steps allows for one point "
                         "(a stiffness or frequency far outside the model's range?)",
}

NAN_LABELS_REASON = ("label(s) {} not a number: the parameters are outside what the simulator resolves "
                     "(a mass, stiffness or frequency many orders of magnitude off)")

METHODS = ("auto", "exact", "dopri5")


@dataclass(frozen=True)
class Settings:
    """Numerical settings of a run (all in forcing cycles unless stated).

    rtol: relative tolerance of the DOPRI5 error control (absolute tolerance of each state =
    rtol × the model's typical magnitude of that state).  The default 1e-7 gives labels within
    ~1e-6 of the tight reference (bench/README.md), better than scipy RK45 at rtol 1e-6.  min_transient / max_transient:
    cycles discarded before the window (settlement is detected in between).  window:
    recorded cycles.  method: "auto" (the model's exact propagator where it applies, sim/exact/: every phase of
    the drill, the RIMD's free flight with its contact on DOPRI5, every phase of the indenters while their seal
    friction is constant with DOPRI5 across its reversals; else DOPRI5), "exact" (error if unavailable) or
    "dopri5" (always the numerical integrator).  period_tol: tolerance of the periodicity test relative to each
    bounded coordinate's range.  event_tol: switch location tolerance as a fraction of
    the period.  samples_per_cycle: history sampling when a history is requested.  max_steps_per_cycle / max_steps:
    work limits, per forcing cycle and for the whole run (accepted steps); past either the run ends ``failed`` with
    its reason (typical runs take 10^4-10^5 steps in all).
    """

    rtol: float = 1e-7
    min_transient: int = 20
    max_transient: int = 400
    window: int = 32
    period_tol: float = 1e-3
    settle_tol: float = 5e-4
    max_steps_per_cycle: int = 200_000
    max_steps: int = 5_000_000
    event_tol: float = 1e-10
    max_step_frac: float = 0.05
    stat_tol: float = 0.05
    samples_per_cycle: int = 400
    method: str = "auto"

    def validate(self) -> "Settings":
        checks = {
            "rtol": 0 < self.rtol < 1, "min_transient": self.min_transient >= 0,
            "max_transient": self.max_transient >= self.min_transient, "window": self.window >= 2,
            "period_tol": self.period_tol > 0, "settle_tol": self.settle_tol > 0,
            "max_steps_per_cycle": self.max_steps_per_cycle > 10, "max_steps": self.max_steps >= 1000,
            "event_tol": 0 < self.event_tol < 1e-3,
            "max_step_frac": 0 < self.max_step_frac <= 1, "stat_tol": self.stat_tol > 0,
            "samples_per_cycle": self.samples_per_cycle >= 2,
            "method": self.method in METHODS,
        }
        for name, ok in checks.items():
            if not ok:
                raise ParameterError(f"setting '{name}' has an invalid value {getattr(self, name)!r}")
        return self

    def to_array(self, runaway_check: bool = False) -> np.ndarray:
        s = np.zeros(I.N_SETTINGS)
        s[I.S_RTOL] = self.rtol
        s[I.S_MIN_TRANSIENT] = self.min_transient
        s[I.S_MAX_TRANSIENT] = self.max_transient
        s[I.S_WINDOW] = self.window
        s[I.S_PERIOD_TOL] = self.period_tol
        s[I.S_SETTLE_TOL] = self.settle_tol
        s[I.S_MAX_STEPS_PER_CYCLE] = self.max_steps_per_cycle
        s[I.S_EVENT_TOL] = self.event_tol
        s[I.S_MAX_STEP_FRAC] = self.max_step_frac
        s[I.S_STAT_TOL] = self.stat_tol
        s[I.S_RUNAWAY_CHECK] = 1.0 if runaway_check else 0.0
        s[I.S_MAX_STEPS] = self.max_steps
        return s


SETTING_NAMES = tuple(f for f in Settings.__dataclass_fields__)


def run_settings(st: Settings, values: dict) -> Settings:
    """``st`` for the run of ``values``: a run left to settle (min_transient < max_transient) of a rig that never
    settles and says how long it ran before its record (``sim.models.discrepancy.run_cycles``) has that transient;
    a transient the caller fixed stands (e.g. 0: a record from rest)."""
    n = run_cycles(values)
    if n and st.min_transient < st.max_transient:
        return replace(st, min_transient=n, max_transient=n).validate()
    return st


def make_settings(spec: ModelSpec, settings: Settings | dict | None) -> Settings:
    base = Settings(**{k: v for k, v in spec.default_settings.items()})
    if settings is None:
        return base.validate()
    if isinstance(settings, Settings):
        return settings.validate()
    unknown = sorted(set(settings) - set(SETTING_NAMES))
    if unknown:
        raise ParameterError(f"unknown setting(s) {unknown}{did_you_mean(unknown[0], SETTING_NAMES)}; "
                             f"known: {', '.join(SETTING_NAMES)}")
    return replace(base, **settings).validate()


@dataclass
class SimulationResult:
    """Labels of one run (MODELS.md §5) and, if requested, its time history."""

    model: str
    params: dict[str, float]
    labels: dict
    columns: dict[str, np.ndarray] | None = None   # the history's columns (t_s [s], states, signals [SI]), or None
    settings: Settings = field(default_factory=Settings)
    final_state: tuple | None = None   # (y, z, phase) at the end: pass as initial_state to continue
    initial_state: tuple | None = None  # the state the run started from (None: rest, MODELS.md)
    history_times: np.ndarray | None = None   # the history's times from the window start, when chosen by the caller
    _frame: "pd.DataFrame | None" = field(default=None, init=False, repr=False, compare=False)

    @property
    def history(self) -> "pd.DataFrame | None":
        """The time history as a DataFrame (built from ``columns`` on first use; None without a history)."""
        if self._frame is None and self.columns is not None:
            import pandas as pd

            self._frame = pd.DataFrame(self.columns)     # one constructor: column-by-column insertion costs ~1 ms
        return self._frame

    def set_column(self, name: str, values: np.ndarray) -> None:
        """Add or replace a history column (the DataFrame is rebuilt on its next use)."""
        self.columns[name] = np.asarray(values)
        self._frame = None

    @property
    def status(self) -> str:
        return self.labels["status"]


def _power_w(energy_per_cycle_j, frequency_hz: float) -> float | None:
    """Mean excitation power [W] = energy per cycle [J] × frequency [Hz]; None where the energy is None."""
    return None if energy_per_cycle_j is None else float(energy_per_cycle_j) * float(frequency_hz)


def _labels_from_vector(v: np.ndarray, precheck_msg: str | None, spec: ModelSpec, values: dict) -> dict:
    """The labels of one run's kernel vector ``v``, checked against the invariants of every result (sim.invariants):
    a result that breaks one is ``failed`` with that reason and no labels."""
    status_code = int(v[I.L_STATUS])
    status = STATUS_NAMES[status_code]
    reason = REASONS.get(int(v[I.L_REASON]), "")
    if status == "runaway" and precheck_msg:
        drift = v[I.L_DRIFT_ACC]
        reason = precheck_msg + (f"; confirmed by the drift: the bit's progression accelerates at {drift:.3g} m/s^2"
                                 if int(v[I.L_REASON]) == I.REASON_DRIFT else "")
    out = {}
    valid = status in BOUNDED_STATUSES
    idxs = (I.L_ROP, I.L_PEAK_F, I.L_MEAN_PEAK_F, I.L_IMPACTS, I.L_PERIOD, I.L_DECEL, I.L_ENERGY, I.L_SPEC_E)
    lost = [name for name, idx in zip(KERNEL_LABELS, idxs) if math.isnan(float(v[idx]))]
    if valid and lost:     # a label is null only with a failure status and a reason
        status, valid = "failed", False
        reason = NAN_LABELS_REASON.format(", ".join(lost))
    for name, idx in zip(KERNEL_LABELS, idxs):
        val = float(v[idx])
        if not valid or (math.isnan(val)):
            out[name] = None
        else:
            out[name] = int(val) if name == "period" else val
    out["status"] = status
    out["reason"] = reason
    broken = violation(out, int(v[I.L_WINDOW]), spec.min_work_per_m, values)
    if broken is not None:
        out.update(dict.fromkeys(KERNEL_LABELS), status="failed", reason=f"invariant broken: {broken}")
    out["transient_cycles"] = int(v[I.L_TRANSIENT])
    out["n_steps"] = int(v[I.L_STEPS])
    out["n_events"] = int(v[I.L_EVENTS])
    return out


def _exact_module(spec: ModelSpec, values: dict, st: Settings, history: bool) -> str | None:
    """The exact propagator to use for this run (None: the numerical integrator)."""
    if st.method == "dopri5" or spec.exact is None:
        if st.method == "exact":
            raise ParameterError(f"setting 'method': model '{spec.name}' has no exact propagator")
        return None
    import importlib

    mod = importlib.import_module(spec.exact)
    # a discrepancy term changes a phase the propagator takes as linear: those runs are numerical
    ok = mod.exact_applies(values, spec.effects) and not any_on(values, spec.discrepancy)
    if st.method == "exact":
        if not ok:
            when = getattr(mod, "APPLIES_WHEN", None)    # a condition beyond the effects, stated by the module
            why = (f"applies only with {when}" if when else
                   f"does not handle the active effects (handles {', '.join(mod.HANDLED_EFFECT_PARAMS)})")
            raise ParameterError(f"setting 'method': the exact propagator of '{spec.name}' {why}")
        if history:
            raise ParameterError("setting 'method': the exact propagator returns no time history; use 'auto'")
        return spec.exact
    return spec.exact if ok and not history else None


def _prepare(spec: ModelSpec, values: dict[str, float], rtol: float):
    """Kernel inputs: parameter vector, initial state, phase, period and absolute tolerances
    (rtol × the model's typical magnitude of each state)."""
    p = spec.vector(values)
    y0, z0, ph0 = spec.initial(p)
    period = 1.0 / values["frequency_hz"]
    return p, y0, z0, int(ph0), period, rtol * np.asarray(spec.atol(p), dtype=np.float64)


def _main_thread_aot(spec: ModelSpec, exact: str | None):
    """The ahead-of-time kernel (sim.aot: no numba import), if built for the current sources and called on the
    main thread (it holds the GIL; threads keep the GIL-free JIT kernel).  Same labels, bit for bit."""
    if threading.current_thread() is not threading.main_thread() or os.environ.get("VIBRO_NO_AOT"):
        return None
    from sim import aot

    return aot.load(spec.funcs, exact)


def _check_state(spec: ModelSpec, state, n_z: int) -> tuple[np.ndarray, np.ndarray, int]:
    """``state`` = (y, z, phase) checked against the model: ``n_z`` is the size of the kernel's discrete-state
    array (``spec.initial``'s; at least 1, and the indenters share one of 2 whether they use it or not)."""
    try:
        y, z, ph = state
        y = np.array(y, dtype=np.float64)
        z = np.array(z, dtype=np.float64)
        ph = int(ph)
    except (TypeError, ValueError):
        raise ParameterError("initial_state must be (y, z, phase) as returned in SimulationResult.final_state") from None
    if y.shape != (len(spec.states),) or not np.all(np.isfinite(y)):
        raise ParameterError(f"initial_state: y must hold {len(spec.states)} finite values ({', '.join(spec.states)})")
    if z.shape != (n_z,) and z.shape != (len(spec.z_names),):
        raise ParameterError(f"initial_state: z must hold the discrete states ({', '.join(spec.z_names) or 'none'})")
    return y, np.concatenate([z, np.zeros(n_z - z.size)]) if z.size < n_z else z, ph


def _check_times(times, period: float, window: int) -> np.ndarray:
    """``history_times`` as a float array: finite, non-decreasing, inside the window [0, window × period] [s]."""
    try:
        t = np.array(times, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise ParameterError("history_times must be a sequence of times [s]") from None
    span = window * period
    if t.size and (not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0) or t[0] < 0.0 or t[-1] > span * (1 + 1e-12)):
        raise ParameterError(f"history_times must be finite, non-decreasing and within the window [0, {span:.6g}] s")
    return t


def simulate(model: str, preset: str | None = None, settings: Settings | dict | None = None,
             history: bool = False, initial_state=None, history_times=None, **params) -> SimulationResult:
    """Simulate one parameter point of ``model`` to a labelled steady state.

    ``params`` override the model defaults (after ``preset``) by name, e.g.
    ``simulate("drill", preset="lab", frequency_hz=120, amplitude_n=800)``.
    With ``history=True`` the recorded window is returned as a DataFrame sampled
    uniformly (``settings.samples_per_cycle`` per cycle): time ``t_s``, every state,
    the phase, contact force ``force_n``, acceleration ``accel_m_s2``, displacement
    ``disp_m`` and velocity ``vel_m_s`` of the impacting mass and ``progression_m``.
    ``initial_state`` = ``(y, z, phase)`` (e.g. a previous result's ``final_state``) starts
    from that state instead of rest — used by continuation sweeps (bifurcation diagrams,
    up/down frequency sweeps); time restarts at 0, i.e. at the same forcing phase as the
    end of the previous run's last whole cycle.
    ``history_times`` (implies ``history``): sample the history at these times [s] from the window start instead
    (non-decreasing, within the window), e.g. a data-acquisition system's own instants; the samples come from the
    integrator's dense output, not from an interpolated grid.
    """
    spec = get_model(model)
    values = spec.resolve(preset, **params)
    st = run_settings(make_settings(spec, settings), values)
    p, y0, z0, ph0, period, atol = _prepare(spec, values, st.rtol)
    msg = spec.precheck(p)
    s = st.to_array(runaway_check=msg is not None)
    chosen = None
    if history_times is not None:
        chosen = _check_times(history_times, period, st.window)
        history = True
        n = chosen.size
        ht = chosen.copy()
    elif history:
        n = st.window * st.samples_per_cycle
        ht = np.arange(n) * (period / st.samples_per_cycle)
    else:
        n = 0
        ht = np.empty(0)
    hy = np.zeros((n, y0.shape[0]))
    ho = np.zeros((n, I.N_OBS))
    hp = np.zeros(n, dtype=np.int64)
    if initial_state is not None:
        y0, z0, ph0 = _check_state(spec, initial_state, z0.shape[0])
    start = None if initial_state is None else (y0.copy(), z0.copy(), int(ph0))
    y, z, ph = y0.copy(), z0.copy(), np.array([ph0], dtype=np.int64)
    exact = _exact_module(spec, values, st, history)
    run_one = _main_thread_aot(spec, exact)
    if run_one is None:
        announce_compile(spec, exact)
        run_one = kernels(spec.funcs, spec.n_bounded, exact)
    v = run_one(p, y, z, ph, period, s, atol, ht, hy, ho, hp)
    labels = _labels_from_vector(v, msg, spec, values)
    cols = None
    if history and labels["status"] not in ("runaway", "failed"):
        cols = {"t_s": ht, **{name: hy[:, i] for i, name in enumerate(spec.states)}, "phase": hp,
                **{name: ho[:, i] for i, name in enumerate(("force_n", "accel_m_s2", "disp_m", "progression_m",
                                                            "vel_m_s"))}}
    res = SimulationResult(model=spec.name, params=values, labels=labels, columns=cols, settings=st,
                           final_state=(y, z, int(ph[0])), initial_state=start, history_times=chosen)
    if spec.postprocess is not None:
        res = spec.postprocess(res)
    res.labels["power_w"] = _power_w(res.labels.get("energy_per_cycle_j"), values["frequency_hz"])
    return res


def simulate_batch(model: str, table, preset: str | None = None, settings: Settings | dict | None = None,
                   n_threads: int | None = None) -> "pd.DataFrame":
    """Simulate every row of ``table`` (DataFrame or list of dicts of parameter overrides) in parallel.

    Returns a DataFrame: the full resolved parameters of each row, every label of MODELS.md §5,
    ``status`` and ``reason``.  Rows are validated first; a bad value raises ParameterError naming
    the row and the column, before anything runs.
    """
    import pandas as pd

    spec = get_model(model)
    df = pd.DataFrame(table).reset_index(drop=True)
    st = make_settings(spec, settings)
    rows = []
    for i, rec in enumerate(df.to_dict("records")):
        rec = {k: v for k, v in rec.items() if not (isinstance(v, float) and math.isnan(v) and k not in spec.param_names)}
        try:
            values = spec.resolve(preset, **rec)
        except ParameterError as e:
            raise ParameterError(f"row {i}: {e}") from None
        rows.append(values)
    if not rows:
        return pd.DataFrame(columns=list(spec.param_names) + list(LABELS) + ["status", "reason"] + list(DIAGNOSTICS))
    prepared = [_prepare(spec, v, st.rtol) for v in rows]
    P = np.stack([x[0] for x in prepared])
    Y0 = np.stack([x[1] for x in prepared])
    Z0 = np.stack([x[2] for x in prepared])
    PH0 = np.array([x[3] for x in prepared], dtype=np.int64)
    periods = np.array([x[4] for x in prepared])
    ATOL = np.stack([x[5] for x in prepared])
    msgs = [spec.precheck(x[0]) for x in prepared]
    flagged = np.array([m is not None for m in msgs])
    out = np.empty((len(rows), I.N_LABELS))
    exact = [_exact_module(spec, v, st, False) for v in rows]
    for e in set(exact):
        announce_compile(spec, e)
    runners = {e: kernels(spec.funcs, spec.n_bounded, e) for e in set(exact)}
    arrays = [run_settings(st, v).to_array(runaway_check=bool(flag)) for v, flag in zip(rows, flagged)]
    empty = (np.empty(0), np.empty((0, Y0.shape[1])), np.empty((0, I.N_OBS)), np.empty(0, dtype=np.int64))

    def work(i: int) -> None:  # run_one releases the GIL: threads run on all cores
        out[i] = runners[exact[i]](P[i], Y0[i].copy(), Z0[i].copy(), PH0[i:i + 1].copy(), periods[i],
                         arrays[i], ATOL[i], *empty)

    workers = n_threads or os.cpu_count() or 1
    if workers == 1 or len(rows) == 1:
        for i in range(len(rows)):
            work(i)
    else:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(work, range(len(rows))))
    labels = [_labels_from_vector(out[i], msgs[i], spec, rows[i]) for i in range(len(rows))]
    res = pd.concat([pd.DataFrame(rows), pd.DataFrame(labels)], axis=1)
    for i, values in enumerate(rows):
        if spec.needs_history(values):   # e.g. the sensor low-pass works on the time history
            r = simulate(model, settings=st, **{k: v for k, v in values.items()})
            for k, v in r.labels.items():
                res.at[i, k] = v
    res["power_w"] = [_power_w(None if pd.isna(e) else e, f)
                      for e, f in zip(res["energy_per_cycle_j"], res["frequency_hz"])]
    return res
