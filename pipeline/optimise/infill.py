"""Infill until the surrogate is right where it is used.

When the simulator contradicts a surrogate study's verification, :func:`infill_until_right` simulates points where
the study looked (a :class:`NearIncumbent` design: along the active limits and around the incumbent, on the box's
faces it touches), appends them with the verified points to the feedback file, retrains the surrogate on its sweep
plus every row of that file this loop wrote, searches and verifies again; at most ``config.infill_rounds`` rounds.
``outcome.optimise`` calls it and falls back to a study on the simulator when the last round still fails.  Each
round is an :class:`InfillRound`; :class:`InfillReport` is what report.json keeps of the loop.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Callable, Protocol

import numpy as np
import pandas as pd

from pipeline.optimise.evaluators import SimulatorEvaluator
from pipeline.optimise.space import Space
from pipeline.optimise.verify import append_feedback, read_feedback, summarise
from pipeline.optimise.workflow import OptimiseResult, plan_optimise, run_optimise, surrogate_failed
from vibrobase.unitcube import from_unit

SCHEMA = 1
"""Version of :meth:`InfillReport.to_json`."""


@dataclass(frozen=True)
class InfillRound:
    """One search on the surrogate and its verification (round 0: the surrogate as given), then the points added.

    Errors are relative ROP errors at the verified points [-]; ROP in m/s; params: the recommendation's controls
    (frequency_hz [Hz], amplitude_n [N], static_force_n [N]), None when nothing was recommended."""
    round: int
    study_name: str
    n_train: int | None                 # rows the round's surrogate was fitted on (its sweep's split + rows added)
    n_verified: int
    n_wrong: int
    rop_rel_error_median: float | None
    rop_rel_error_max: float | None
    recommendation_wrong: bool
    rop_m_s_sim: float | None
    rop_m_s_pred: float | None
    params: dict | None
    failed: str | None                  # why the surrogate failed its verification, None when it passed
    points_added: int = 0               # infill points simulated after this round (0 on the last)

    @property
    def simulations(self) -> int:
        """Simulator calls of the round: its verification and its infill points."""
        return self.n_verified + self.points_added


@dataclass(frozen=True)
class InfillReport:
    """The infill loop as report.json keeps it: every round, the extra simulations, where the data came from."""
    rounds: tuple[InfillRound, ...]
    simulations: int                    # simulator calls beyond round 0's verification: infill + later verifications
    train_data: str | None              # the sweep retrained on
    feedback: str | None                # the file the simulated points went to and were read back from
    note: str | None = None             # why no round ran

    @property
    def agreed(self) -> bool:
        """The last round's surrogate passed its verification."""
        return bool(self.rounds) and self.rounds[-1].failed is None

    @property
    def n_rounds(self) -> int:
        """Infill rounds run (round 0 not counted)."""
        return max(len(self.rounds) - 1, 0)

    def to_json(self) -> dict:
        return {"schema": SCHEMA, "rounds": [{**asdict(r), "simulations": r.simulations} for r in self.rounds],
                "n_rounds": self.n_rounds, "simulations": self.simulations, "agreed": self.agreed,
                "train_data": self.train_data, "feedback": self.feedback, "note": self.note,
                "lines": self.lines(), "text": self.text()}

    @classmethod
    def from_json(cls, d: dict) -> "InfillReport":
        if d.get("schema") != SCHEMA:
            raise ValueError(f"infill report schema {d.get('schema')!r}, this vibro reads {SCHEMA}")
        fields = set(InfillRound.__dataclass_fields__)
        return cls(tuple(InfillRound(**{k: v for k, v in r.items() if k in fields}) for r in d["rounds"]),
                   d["simulations"], d.get("train_data"), d.get("feedback"), d.get("note"))

    def lines(self) -> list[str]:
        """One line per round (the printed answer and report.md)."""
        out = []
        for r in self.rounds:
            med = "—" if r.rop_rel_error_median is None else f"{r.rop_rel_error_median:.1%}"
            rec = ("nothing recommended" if r.rop_m_s_sim is None else
                   f"recommends {r.rop_m_s_sim * 1e3:.4g} mm/s (predicted "
                   f"{'—' if r.rop_m_s_pred is None else format(r.rop_m_s_pred * 1e3, '.4g')}) at "
                   + ", ".join(f"{n} = {v:.4g}" for n, v in (r.params or {}).items()))
            out.append(f"round {r.round}: wrong at {r.n_wrong} of {r.n_verified} verified points (median ROP error "
                       f"{med}){', the recommended one among them' if r.recommendation_wrong else ''}; {rec}"
                       + (f"; {r.points_added} points added" if r.points_added else ""))
        return out

    def text(self) -> str:
        """One sentence: how the loop ended."""
        if self.note:
            return f"infill: {self.note}"
        end = ("the surrogate agrees with the simulator" if self.agreed else
               "the surrogate still fails its verification")
        return (f"infill: {self.n_rounds} round(s), {self.simulations} extra simulations; {end} "
                f"(retrained on {self.train_data} + the points in {self.feedback})")


@dataclass(frozen=True)
class InfillOutcome:
    """The loop's report and the last round's result (the one to recommend from, unless it failed)."""
    report: InfillReport
    result: OptimiseResult
    feedback_rows: int | None = None    # rows now in the feedback file


def round_record(res: OptimiseResult, k: int, n_train: int | None, points_added: int = 0) -> InfillRound:
    """The :class:`InfillRound` of a verified surrogate study."""
    s = summarise(res.verified) if res.verified is not None and len(res.verified) else {}
    rec = res.recommendation or {}
    return InfillRound(k, res.study_name, n_train, res.n_verified, res.n_surrogate_wrong,
                       s.get("rop_rel_error_median"), s.get("rop_rel_error_max"), bool(rec.get("surrogate_wrong")),
                       rec.get("rop_m_s_sim"), rec.get("rop_m_s_pred"), rec.get("params"), surrogate_failed(res),
                       points_added)


# ------------------------------------------------------------------ where to simulate
class InfillDesign(Protocol):
    """Points (one row each, the space's inputs) to simulate after the verified study ``res``."""

    def __call__(self, res: OptimiseResult, n: int, seed: int) -> pd.DataFrame: ...


def incumbent(res: OptimiseResult) -> dict:
    """The study's best guess: the recommendation, else the verified point the surrogate ranked first, else the
    best trial."""
    names = res.problem.space.names
    if res.recommendation is not None:
        return dict(res.recommendation["params"])
    rows = res.verified if res.verified is not None and len(res.verified) else res.trials.sort_values("value")[::-1]
    return {n: float(rows.iloc[0][n]) for n in names}


@dataclass(frozen=True)
class NearIncumbent:
    """Half the points along the limits the study ran into: its trials whose predicted limited label (power_w,
    peak_decel_g, peak_force_n, ...) lies within ``band`` (fraction of the limit) of it, nearest the incumbent; the
    rest scattered (Sobol') in a box of ``radius`` (fraction of each range) around the incumbent, every other one
    kept on the faces of the search box the incumbent lies on.  No two points (nor a point and a verified one)
    closer than ``min_dist`` in the unit cube."""
    radius: float = 0.1
    band: float = 0.05
    min_dist: float = 0.01

    def __call__(self, res: OptimiseResult, n: int, seed: int) -> pd.DataFrame:
        space = res.problem.space
        inc = incumbent(res)
        u0 = space.unit(pd.DataFrame([inc]))[0]
        taken = list(space.unit(res.verified)) if res.verified is not None and len(res.verified) else []
        picked = self._on_limits(res, u0, n // 2, taken)
        picked += self._around(space, u0, inc, n - len(picked), seed, taken + picked)
        return _values(space, np.array(picked).reshape(-1, len(space.names)))

    def _far(self, u, taken) -> bool:
        return all(np.linalg.norm(u - t) >= self.min_dist for t in taken)

    def _on_limits(self, res: OptimiseResult, u0, n: int, taken: list) -> list:
        trials = res.trials
        if n <= 0 or not len(trials):
            return []
        limits = [k for k in res.constraints.names() if k not in ("steady_state", "progress")]
        if not limits:
            return []
        near = np.array([any(abs(v) <= self.band for k, v in res.constraints.values(row).items() if k in limits)
                         for row in trials.to_dict("records")])
        if not near.any():
            return []
        U = res.problem.space.unit(trials[near])
        out: list = []
        for i in np.argsort(np.linalg.norm(U - u0, axis=1)):
            if self._far(U[i], taken + out):
                out.append(U[i])
                if len(out) >= n:
                    break
        return out

    def _around(self, space: Space, u0, inc: dict, n: int, seed: int, taken: list) -> list:
        from scipy.stats import qmc

        if n <= 0:
            return []
        faces = {space.names.index(h["name"]): 0.0 if h["side"] == "low" else 1.0 for h in space.on_bounds(inc)}
        m = 1 << max(int(math.ceil(math.log2(4 * n))), 1)       # a few times more than needed: some are too close
        box = qmc.Sobol(len(u0), scramble=True, seed=seed).random(m)
        U = np.clip(u0 + self.radius * (2.0 * box - 1.0), 0.0, 1.0)
        for j, side in faces.items():
            U[::2, j] = side
        out: list = []
        for u in U:
            if self._far(u, taken + out):
                out.append(u)
                if len(out) >= n:
                    break
        return out


def _values(space: Space, U: np.ndarray) -> pd.DataFrame:
    """Unit-cube rows -> the space's values."""
    return pd.DataFrame({n: from_unit(U[:, j], lo, hi, n in space.log) for j, (n, (lo, hi)) in
                         enumerate(space.ranges.items())})


# ------------------------------------------------------------------ the loop
SETTLED_GAIN = 0.01
"""A round whose surrogate agrees but whose recommendation gained more than this fraction of simulated ROP over the
round before is followed by another: where the surrogate is used has moved, the optimum may still move with it."""


def _moved(before: InfillRound, res: OptimiseResult) -> bool:
    """The recommendation of ``res`` gained more than :data:`SETTLED_GAIN` of simulated ROP over ``before``'s."""
    now = (res.recommendation or {}).get("rop_m_s_sim")
    if now is None or before.rop_m_s_sim is None:
        return False
    return now > (1.0 + SETTLED_GAIN) * before.rop_m_s_sim


Retrain = Callable[[pd.DataFrame], object]
"""Simulated rows -> the surrogate retrained on its sweep plus those rows."""
Build = Callable[[object, object], object]
"""(OptimiseConfig, bundle) -> Strategies of a study on that bundle (``strategies.build_strategies``)."""


def surrogate_retrainer(bundle, train_data: str | None, progress: bool = False) -> tuple[Retrain | None, str | None]:
    """(retrain, the sweep's path) for ``bundle``: its sweep ``train_data``, else the dataset its report names, with
    the bundle's training settings (no learning curve); (None, why) when there is no sweep to retrain on."""
    from pipeline.training.workflow import load_training_data, retrain
    from surrogate.config import TrainConfig

    path = train_data or (getattr(bundle, "report", None) or {}).get("dataset")
    if not path:
        return None, ("no sweep to retrain the surrogate on: its report names none; give --train-data (the "
                      "sweep it was trained on)")
    if not Path(path).exists():
        return None, f"the surrogate's sweep {path} is not there; give --train-data"
    data = load_training_data(str(path), bundle.model, list(bundle.inputs))
    if getattr(bundle, "fingerprint", None) and data.fingerprint != bundle.fingerprint:
        return None, (f"{path} is not the sweep the surrogate was trained on (its fingerprint differs); give the "
                      "surrogate's own sweep with --train-data")
    # the bundle's conditions are what it stands for: its preset, fixed values (a rig's), settings and box
    data = replace(data, preset=bundle.preset, meta={**data.meta, "fixed": dict(bundle.fixed or {}),
                                                     "settings": dict(bundle.settings or {})},
                   ranges={n: tuple(map(float, r)) for n, r in bundle.ranges.items()})
    cfg = TrainConfig.from_dict({**(bundle.config or {}), "learning_curve": []})
    return (lambda extra: retrain(data, cfg, extra, progress=progress)), str(path)


def infill_until_right(first: OptimiseResult, bundle, build: Build, feedback: str, design: InfillDesign | None = None,
                       progress: bool = True, notify: Callable[[str], None] | None = None) -> InfillOutcome:
    """Rounds of infill after the surrogate study ``first`` failed its verification (its verified points already in
    ``feedback``): simulate ``infill_points`` points of ``design`` (default :class:`NearIncumbent`), append them to
    ``feedback``, retrain ``bundle`` on its sweep plus every row this loop's studies wrote there, search and verify
    again with ``build``; stop when the surrogate passes or after ``infill_rounds`` rounds.  ``notify`` is told, in
    one line, what each round retrains on."""
    cfg = first.config
    design = design or NearIncumbent()
    retrain, where = surrogate_retrainer(bundle, cfg.train_data, progress=progress)
    n0 = (getattr(bundle, "report", None) or {}).get("n_train")
    if retrain is None:
        return InfillOutcome(InfillReport((round_record(first, 0, n0),), 0, None, feedback, note=where), first)
    p = first.problem
    simulator = SimulatorEvaluator(p.model, p.preset, p.fixed, settings=p.settings, n_threads=cfg.n_threads)
    res, records, studies, extra_sims, n_rows = first, [], [first.study_name], 0, None
    for k in range(1, cfg.infill_rounds + 1):
        X = design(res, cfg.infill_points, seed=cfg.seed + k)
        if len(X):
            simres = simulator(X)
            n_rows = append_feedback(simres, feedback, source="optimise-infill", study=res.study_name,
                                     inputs=p.space.names)
        records.append(round_record(res, k - 1, n0, points_added=len(X)))
        extra_sims += len(X)
        rows = read_feedback(feedback, studies)
        if notify is not None:
            notify(f"infill round {k}: retraining the surrogate with {len(rows)} simulated points")
        new = retrain(rows)
        n0 = new.report.get("n_train")
        name = f"{cfg.study_name}-infill{k}" if cfg.study_name else None
        round_cfg = replace(cfg, study_name=name)
        res = run_optimise(plan_optimise(round_cfg, build(round_cfg, new)), progress=progress)
        extra_sims += res.n_verified
        if res.simulated is not None:
            n_rows = append_feedback(res.simulated, feedback, source=f"optimise-{cfg.mode}", study=res.study_name,
                                     wrong=res.verified["surrogate_wrong"].tolist(), inputs=p.space.names)
        studies.append(res.study_name)
        if surrogate_failed(res) is None and not _moved(records[-1], res):
            break
    records.append(round_record(res, len(records), n0))
    return InfillOutcome(InfillReport(tuple(records), extra_sims, where, feedback), res, n_rows)
