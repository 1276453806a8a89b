"""Training configuration: the ``train`` section of params.yaml (every key optional)."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

from surrogate.data import DEFAULT_DOMAINS
from surrogate.errors import ConfigError
from surrogate.names import TARGETS


def _known_keys(d, cls, where: str) -> None:
    """ConfigError naming the keys of the mapping ``d`` that are not fields of the dataclass ``cls``."""
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(d) - known)
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {unknown}; known: {', '.join(sorted(known))}")


@dataclass
class AdaptiveConfig:
    """Adaptive sampling (``vibro train --adaptive``): start from ``initial`` Sobol points, then add
    ``batch`` points per round chosen from a Sobol pool of ``pool`` candidates where the regime
    classifier is least sure or the ROP ensemble disagrees most, until ``budget`` simulations."""

    enabled: bool = False
    initial: int = 128
    batch: int = 64
    budget: int = 768
    pool: int = 4096
    boundary_weight: float = 0.5
    ensemble: int = 5


@dataclass
class TrainConfig:
    test_fraction: float = 0.2
    cv_folds: int = 5
    seed: int = 0
    targets: list[str] = field(default_factory=lambda: list(TARGETS))
    regressors: list[str] = field(default_factory=lambda: ["gp", "gbt", "mlp"])
    classifiers: list[str] = field(default_factory=lambda: ["gbt", "mlp", "trees"])
    transforms: dict[str, str] = field(default_factory=dict)          # target -> auto | log | identity
    domains: dict[str, str] = field(default_factory=lambda: dict(DEFAULT_DOMAINS))
    max_gp_points: int = 600
    threads: int = 1            # BLAS/OpenMP threads per fitting process (the machine is shared)
    workers: int | None = None  # processes fitting CV folds and learning-curve sizes at once (None: all cores);
    #                             the result does not depend on it
    interval: float = 0.9
    learning_curve: list[float] = field(default_factory=lambda: [0.1, 0.2, 0.35, 0.5, 1.0])   # 1.0: the bundle itself
    goals: dict[str, float] = field(default_factory=lambda: {"rop_m_s_r2": 0.95, "peak_force_n_r2": 0.97,
                                                             "accuracy": 0.97, "coverage_low": 0.85,
                                                             "coverage_high": 0.95})
    adaptive: AdaptiveConfig = field(default_factory=AdaptiveConfig)

    @classmethod
    def from_dict(cls, d: dict | None) -> "TrainConfig":
        d = dict(d or {})
        _known_keys(d, cls, "train")
        ad = d.pop("adaptive", None) or {}
        _known_keys(ad, AdaptiveConfig, "train.adaptive")
        cfg = cls(**d, adaptive=AdaptiveConfig(**ad))
        merged = dict(DEFAULT_DOMAINS)
        merged.update(cfg.domains)
        cfg.domains = merged
        cfg.validate()
        return cfg

    def validate(self) -> None:
        if not 0.05 <= self.test_fraction <= 0.5:
            raise ConfigError(f"train.test_fraction must be in [0.05, 0.5], got {self.test_fraction}")
        if self.workers is not None and not (isinstance(self.workers, int) and self.workers >= 1):
            raise ConfigError(f"train.workers must be a whole number >= 1 or null (all cores), got {self.workers!r}")
        if self.cv_folds < 2:
            raise ConfigError(f"train.cv_folds must be >= 2, got {self.cv_folds}")
        if not 0.5 < self.interval < 1:
            raise ConfigError(f"train.interval must be in (0.5, 1), got {self.interval}")
        for t in self.targets:
            if t not in TARGETS:
                raise ConfigError(f"train.targets: unknown target '{t}' (choose from {', '.join(TARGETS)})")
        for t, k in self.transforms.items():
            if k not in ("auto", "log", "identity"):
                raise ConfigError(f"train.transforms.{t}: '{k}' is not auto, log or identity")
        from surrogate.candidates import CLASSIFIERS, REGRESSORS

        for key, names, known in (("regressors", self.regressors, REGRESSORS),
                                  ("classifiers", self.classifiers, CLASSIFIERS)):
            for n in names:
                if n not in known:
                    raise ConfigError(f"train.{key}: unknown candidate '{n}' (choose from {', '.join(known)})")
        if not self.regressors or not self.classifiers:
            raise ConfigError("train.regressors and train.classifiers need at least one candidate each")
        if any(not 0 < f <= 1 for f in self.learning_curve):
            raise ConfigError("train.learning_curve: fractions of the training split must be in (0, 1]")
        a = self.adaptive
        if a.initial < 16 or a.batch < 1 or a.budget <= a.initial or a.pool < a.budget:
            raise ConfigError("train.adaptive: need initial >= 16, batch >= 1, initial < budget <= pool")

    def to_dict(self) -> dict:
        return asdict(self)
