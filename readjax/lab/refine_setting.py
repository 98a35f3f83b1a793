"""READ's refinement at inference as a setting that a validation split chooses among
(:mod:`readjax.lab.choice`) and a grid evaluates (:mod:`readjax.lab.pipeline_config`), and the paper's."""

from __future__ import annotations

from dataclasses import dataclass

from readjax.config import REFINE_UPDATES


@dataclass(frozen=True)
class RefineSetting:
    """READ's refinement at inference, as ``experiments.evaluate`` takes it: ``rounds`` refinements in
    a row, each with the ``refine`` update, from SPE's top ``candidates`` retrievals."""
    rounds: int
    refine: str
    candidates: int = 1

    def __post_init__(self):
        if isinstance(self.rounds, bool) or not isinstance(self.rounds, int) or self.rounds < 1:
            raise ValueError(f"a setting's rounds must be a positive integer, got {self.rounds!r}")
        if self.refine not in REFINE_UPDATES:
            raise ValueError(f"a setting's refine must be one of {', '.join(REFINE_UPDATES)}, got {self.refine!r}")
        if isinstance(self.candidates, bool) or not isinstance(self.candidates, int) or self.candidates < 1:
            raise ValueError(f"a setting's candidates must be a positive integer, got {self.candidates!r}")

    def argv(self) -> list[str]:
        """Its ``experiments.evaluate`` flags."""
        return ["--rounds", str(self.rounds), "--refine", self.refine, "--candidates", str(self.candidates)]

    def text(self) -> str:
        return f"rounds={self.rounds},refine={self.refine},candidates={self.candidates}"

    @classmethod
    def parse(cls, text: str) -> "RefineSetting":
        """The inverse of ``text``: ``rounds=R,refine=U[,candidates=C]``."""
        pairs = dict(kv.split("=", 1) for kv in text.split(",") if "=" in kv)
        if set(pairs) - {"rounds", "refine", "candidates"} or not {"rounds", "refine"} <= set(pairs) \
                or len(pairs) != len(text.split(",")):
            raise ValueError(f"a setting looks like rounds=R,refine=U[,candidates=C], got {text!r}")
        try:
            return cls(int(pairs["rounds"]), pairs["refine"], int(pairs.get("candidates", 1)))
        except ValueError as e:
            raise ValueError(f"setting {text!r}: {e}") from None


PAPER_SETTING = RefineSetting(1, "renoise", 1)  # the paper's single re-noising refinement of SPE's top-1
