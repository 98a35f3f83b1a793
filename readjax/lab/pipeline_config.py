"""What a grid of (task x method) work is asked to do: its config (``PipelineConfig``: tasks, methods
and their variants, the paper's other protocols, the validation split and the refinement settings
each READ run chooses among on it, ``ChoiceGrid`` of ``RefineSetting``), the evaluations it asks of
each run (``EvalRequest``: the main table's, ``eval_requests``; the protocols', ``protocol_requests``)
and the recipe each of its labels trains with (``label_configs``, ``recipe``).
``readjax.lab.pipeline`` plans the steps that carry it out.
"""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass, field

from readjax import methods, tasks
from readjax.config import REFINE_UPDATES
from readjax.lab import choice, result_record
from readjax.lab.paper import POOR_RANK
from readjax.lab.refine_setting import RefineSetting


@dataclass(frozen=True)
class ChoiceGrid:
    """The refinement settings a READ run is evaluated with on the validation split, one of which it
    then uses on the test split: every combination of the values below, a value None standing for
    the run's own (its ``sde.rounds``, its ``sde.update``), duplicates collapsed."""
    rounds: tuple[int | None, ...] = (1, None)
    refine: tuple[str | None, ...] = ("renoise", None)
    candidates: tuple[int, ...] = (1,)

    def settings(self, sde) -> tuple[RefineSetting, ...]:
        """The grid for a run whose SDE config is ``sde``, in order, without repeats."""
        combos = itertools.product(self.rounds, self.refine, self.candidates)
        return tuple(dict.fromkeys(RefineSetting(sde.rounds if r is None else r, sde.update if u is None else u, c)
                                   for r, u, c in combos))

    def validate(self) -> None:
        if not (self.rounds and self.refine and self.candidates):
            raise ValueError("the choice grid needs at least one value of rounds, refine and candidates")
        for r in self.rounds:
            if r is not None and (isinstance(r, bool) or not isinstance(r, int) or r < 1):
                raise ValueError(f"--choice-rounds: a positive integer or 'preset', got {r!r}")
        for u in self.refine:
            if u is not None and u not in REFINE_UPDATES:
                raise ValueError(f"--choice-refine: one of {', '.join(REFINE_UPDATES)} or 'preset', got {u!r}")
        for c in self.candidates:
            if isinstance(c, bool) or not isinstance(c, int) or c < 1:
                raise ValueError(f"--choice-candidates: a positive integer, got {c!r}")


@dataclass(frozen=True)
class PipelineConfig:
    tasks: tuple[str, ...]
    methods: tuple[str, ...] = ("read", "deterministic")
    preset: str = "cpu"
    data: str = "data"
    runs: str = "runs"
    results: str = "results"
    train_episodes: int = 1000
    test_episodes: int = 100
    image_size: int = 64
    gen_batch: int = 32
    read_N: tuple[int, ...] = (0, 100)
    overrides: tuple[str, ...] = ()  # --set for every training
    run_names: tuple[tuple[str, str], ...] = ()  # (method, run name); a method not named: its own name
    media_episodes: int = 8  # READ's first k test episodes (at most all) rendered: overlay + video; 0: none
    diagnose_below: float = 80.0  # READ below this % at its largest N: also evaluated from the oracle's start
    # (label, method, overrides): a method trained with its own config overrides, in its own run
    # folder (default: the label), e.g. ("read_o_em", "read_o", ("read_o.sampler=em",)); its label
    # goes in ``methods`` like a method's name
    variants: tuple[tuple[str, str, tuple[str, ...]], ...] = ()
    protocols: tuple[str, ...] = ()  # READ's evaluations beyond the main table: keys of PROTOCOL_EVALUATIONS
    # READ variants (labels of ``methods``) evaluated under ``protocols`` as well as READ itself, e.g. the
    # paper's recipe from a poor start
    protocol_runs: tuple[str, ...] = ()
    noise: float = 0.05  # Table 9's perturbations (the paper does not state its levels): RGB noise std
    brightness: float = 0.7  # and the brightness factor
    # validation episodes (seeds from 2,000,000): each READ run's refinement setting is chosen on
    # them, among ``choice_grid``'s, before its test evaluations; 0: no validation (each READ run
    # is evaluated with its preset's refinement)
    val_episodes: int = 100
    choice_grid: ChoiceGrid = field(default_factory=ChoiceGrid)
    # READ runs (labels of ``methods``) that refine with their own config's setting, chosen on nothing:
    # a recipe reported as it is, e.g. the paper's (renoise, one round)
    fixed_refinement: tuple[str, ...] = ()

    def validate(self) -> "PipelineConfig":
        names = tuple(tasks.canonical_name(t) for t in self.tasks)
        if self.val_episodes < 0:
            raise ValueError(f"--val-episodes must be >= 0, got {self.val_episodes}")
        self.choice_grid.validate()
        for label in self.fixed_refinement:
            if label not in self.methods or self.method_of(label) != "read":
                raise ValueError(f"--fixed-refinement {label}: not a READ run of this grid (its methods and variants: "
                                 f"{', '.join(self.methods)})")
        if self.media_episodes < 0:
            raise ValueError(f"--media-episodes must be >= 0, got {self.media_episodes}")
        if not 0.0 <= self.diagnose_below <= 100.0:
            raise ValueError(f"--diagnose-below is a percentage in [0, 100], got {self.diagnose_below}")
        variant_labels = [label for label, _, _ in self.variants]
        for label, method, sets in self.variants:
            if label in methods.names() or variant_labels.count(label) > 1:
                raise ValueError(f"--variant {label}: the label must differ from every method's name and "
                                 f"every other variant's")
            if not label or "/" in label:
                raise ValueError(f"--variant {label!r}: a label is one folder name")
            methods.module(method)
            bad = [kv for kv in sets if "=" not in kv]
            if bad:
                raise ValueError(f"--variant {label}: overrides look like KEY=VALUE, got {bad}")
        for m in self.methods:
            if m not in variant_labels:
                methods.module(m)
        from readjax import config
        for m in self.methods:  # a bad override fails here, not hours into the grid
            try:
                config.override(config.presets(self.preset), self.overrides_of(m))
            except ValueError as e:
                raise ValueError(f"{m}: {e}") from None
        for m, name in self.run_names:
            if m not in self.methods:
                raise ValueError(f"--run-name names method {m!r}, which is not among --methods {' '.join(self.methods)}")
            if not name or "/" in name:
                raise ValueError(f"--run-name {m}={name!r}: a run name is one folder name")
        unknown = [x for x in self.protocols if x not in PROTOCOL_EVALUATIONS]
        if unknown:
            raise ValueError(f"--protocols: unknown {unknown}; choose among {' '.join(PROTOCOL_EVALUATIONS)}")
        if "poor" in self.protocols and self.train_episodes < POOR_RANK:
            raise ValueError(f"the poor protocol retrieves the {POOR_RANK}th nearest training demonstration: "
                             f"--train-episodes must be at least {POOR_RANK}, got {self.train_episodes}")
        if self.protocols and "read" not in self.methods:
            raise ValueError("--protocols evaluate READ's run: add read to --methods")
        for label in self.protocol_runs:
            if label not in self.methods or self.method_of(label) != "read" or label == "read":
                raise ValueError(f"--protocol-runs {label}: not a READ variant of this grid (its methods and variants: "
                                 f"{', '.join(self.methods)})")
        if self.protocol_runs and not self.protocols:
            raise ValueError("--protocol-runs names the variants evaluated under --protocols: name the protocols too")
        if self.noise < 0 or self.brightness <= 0:
            raise ValueError(f"--noise must be >= 0 and --brightness > 0, got {self.noise} and {self.brightness}")
        if "perturbed" in self.protocols and (self.noise == 0 or self.brightness == 1.0):
            raise ValueError("the perturbed protocol needs --noise > 0 and --brightness != 1 (else it repeats "
                             "the clean evaluation)")
        return PipelineConfig(**{**self.__dict__, "tasks": names})

    def chooses(self, label: str) -> bool:
        """Whether the ``label`` run chooses its refinement on the validation split: a READ run, with
        validation episodes asked for and a largest --read-N that refines, not in ``fixed_refinement``."""
        return (self.val_episodes > 0 and self.method_of(label) == "read" and max(self.read_N) > 0
                and label not in self.fixed_refinement)

    def run_name(self, label: str) -> str:
        """The run folder of a method or variant on each task (``--run-name``; default its label)."""
        return dict(self.run_names).get(label, label)

    def method_of(self, label: str) -> str:
        """The method a label of ``methods`` trains: a variant's, or the label itself."""
        return next((m for lab, m, _ in self.variants if lab == label), label)

    def overrides_of(self, label: str) -> tuple[str, ...]:
        """Config overrides of a label's training: the grid's (``overrides``), then the variant's."""
        return self.overrides + next((sets for lab, _, sets in self.variants if lab == label), ())


@dataclass(frozen=True)
class EvalRequest:
    """One evaluation of a run on the test split: N refinement steps (None: the method's default,
    for a method evaluated once), from SPE's top-1 or the oracle's ``rank``-th nearest training
    demonstration, on clean images or with Gaussian ``noise`` / a ``brightness`` factor on the RGB,
    refined as the run's configs say or as its ``choice`` file says.
    ``experiments.evaluate`` names the result from these options."""
    n: int | None = None
    rank: int | None = None  # None: SPE top-1
    noise: float = 0.0
    brightness: float = 1.0
    # a READ run's choice file (results/<task>/<run>/choice.json): refined (n > 0) with the setting
    # chosen there on the validation split instead of the run's own
    choice: str | None = None

    def argv(self) -> list[str]:
        out = [] if self.n is None else ["--N", str(self.n)]
        if self.choice is not None:
            out += ["--choice", self.choice]
        if self.rank is not None:
            out += ["--retrieval", "cheat", "--rank", str(self.rank)]
        if self.noise:
            out += ["--noise", f"{self.noise:g}"]
        if self.brightness != 1.0:
            out += ["--brightness", f"{self.brightness:g}"]
        return out

    def label(self, method: str) -> str:
        """The step's label (also the key of its recorded wall clock, which prices the ETA of the same
        step on other tasks: the labels of earlier grids are kept)."""
        where = ("" if self.rank is None else " from the oracle's start" if self.rank == 1
                 else f" from the oracle's {_ordinal(self.rank)} neighbour")
        images = "".join([f" on noisy images (std {self.noise:g})" if self.noise else "",
                          f" at brightness x{self.brightness:g}" if self.brightness != 1.0 else ""])
        steps = "" if self.n is None else f" --N {self.n}"
        return f"evaluate {method}{where}{images}{steps}"

    def matches(self, r: dict, method: str) -> bool:
        if self.choice is not None:
            return choice.is_chosen_eval(r, method, self.choice, self.n, self.rank, self.noise, self.brightness)
        return result_record.is_default_eval(r, method, self.n, self.rank, self.noise, self.brightness)


def _ordinal(k: int) -> str:
    return f"{k}{'th' if 10 <= k % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th')}"


# The paper's protocols beyond the main table, each a set of READ evaluations (``--protocols``);
# ``top`` is the largest --read-N.
PROTOCOL_EVALUATIONS = {
    "oracle": "Tables 4 and 5: from the oracle's i-th nearest demonstration, i = 1, 3, 10, at N = 0 and top "
              "(READ-O and READ-L runs too, at their default N: Table 4's rows)",
    "poor": "Table 8: from the oracle's 500th neighbour (a poor retrieval) at N = 0, 1 and top",
    "perturbed": "Table 9: SPE top-1 at N = top on test images with Gaussian noise (--noise) and with a "
                 "brightness factor (--brightness)",
}
ORACLE_RANKS = (1, 3, 10)
# Table 4 also starts the two ablations from the oracle's i-th neighbour (refined at their default N):
# with the oracle protocol, their runs (and variants) are evaluated so too
ORACLE_ABLATIONS = ("read_o", "read_l")


def eval_requests(method: str, read_n) -> list[EvalRequest]:
    """The main-table evaluations of a method: READ at each N, the others once with their defaults."""
    if method == "read":
        return [EvalRequest(n) for n in read_n]
    return [EvalRequest()]


def protocol_requests(cfg: PipelineConfig) -> list[EvalRequest]:
    """READ's evaluations for ``cfg.protocols`` (see ``PROTOCOL_EVALUATIONS``), in that order, without repeats."""
    top, out = max(cfg.read_N), []
    for name in cfg.protocols:
        if name == "oracle":
            out += [EvalRequest(n, rank) for rank in ORACLE_RANKS for n in sorted({0, top})]
        elif name == "poor":
            out += [EvalRequest(n, POOR_RANK) for n in sorted({0, 1, top})]
        elif name == "perturbed":
            out += [EvalRequest(top, noise=cfg.noise), EvalRequest(top, brightness=cfg.brightness)]
    return list(dict.fromkeys(out))


def label_configs(cfg: PipelineConfig, label: str) -> dict:
    """The configs (every section, train included) a ``label`` run of this grid trains with."""
    from readjax import config
    return config.override(config.presets(cfg.preset), cfg.overrides_of(label))


def recipe(cfg: PipelineConfig, label: str) -> dict:
    """Every config section a ``label`` run of this grid is trained with (the preset and the
    overrides), as a result JSON records it."""
    from readjax import config
    configs = label_configs(cfg, label)
    sections = [k for k in configs if k != "train"]
    return json.loads(json.dumps(config.configs_to_dict(configs, sections)))
