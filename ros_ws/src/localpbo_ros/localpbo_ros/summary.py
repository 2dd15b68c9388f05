"""What a finished run produced: logged by the optimizer node, printed by ``localpbo run``."""

from __future__ import annotations

from dataclasses import dataclass


def _theta(values: tuple[float, ...]) -> str:
    return "[" + ", ".join(f"{v:.4f}" for v in values) + "]"


@dataclass(frozen=True)
class RunSummary:
    """The end of a run.

    Attributes:
        run_id: the run.
        state: ``done``, ``failed`` or ``timeout``.
        error: why the run failed (empty when done).
        duels: accepted duel answers, resumed ones included.
        resumed_duels: how many of them came from a resumed bag.
        evaluations: candidates proposed (each evaluated once).
        budget: evaluations the run may use.
        incumbent_id / incumbent_theta: the candidate that won its latest duel (king of the
            hill), θ in task units.
        recommended_id / recommended_theta: the evaluated candidate with the highest posterior
            mean utility given every duel (what to deploy), θ in task units.
        run_seconds / run_cpu_seconds: wall and process CPU time of the optimizer from its
            start to its end.
        wall_seconds: wall time of the whole command (set by ``localpbo run``).
        bag: the bag written (``localpbo run``; empty otherwise).
        messages_recorded: messages the recorder wrote (``localpbo run``).
        recommended_return / incumbent_return / first_candidate_return: their episode
            returns, for the reader only (the optimizer never sees returns).
    """

    run_id: str
    state: str
    error: str
    duels: int
    resumed_duels: int
    evaluations: int
    budget: int
    incumbent_id: int | None
    incumbent_theta: tuple[float, ...]
    recommended_id: int | None
    recommended_theta: tuple[float, ...]
    run_seconds: float
    run_cpu_seconds: float
    wall_seconds: float | None = None
    bag: str = ""
    messages_recorded: int = 0
    recommended_return: float | None = None
    incumbent_return: float | None = None
    first_candidate_return: float | None = None

    def format(self) -> str:
        """Human-readable summary."""
        lines = [
            f"run {self.run_id}: {self.state}" + (f" ({self.error})" if self.error else ""),
            f"duels: {self.duels}"
            + (f" ({self.resumed_duels} from the resumed bag)" if self.resumed_duels else ""),
            f"evaluations: {self.evaluations} of {self.budget}",
        ]
        seconds = self.wall_seconds if self.wall_seconds is not None else self.run_seconds
        lines.append(f"time: {seconds:.1f} s")
        if self.recommended_id is not None:
            lines.append(
                "recommended candidate (highest posterior mean utility given all duels): "
                f"id {self.recommended_id}, θ = {_theta(self.recommended_theta)}"
            )
        if self.incumbent_id is not None:
            lines.append(
                f"incumbent (won its latest duel): id {self.incumbent_id}, "
                f"θ = {_theta(self.incumbent_theta)}"
            )
        returns = [
            (name, value)
            for name, value in (
                ("recommended", self.recommended_return),
                ("incumbent", self.incumbent_return),
                ("first candidate", self.first_candidate_return),
            )
            if value is not None
        ]
        if returns:
            lines.append(
                "episode return (reported, never shown to the optimizer): "
                + ", ".join(f"{name} {value:.1f}" for name, value in returns)
            )
        if self.bag:
            lines.append(f"bag: {self.bag}")
        return "\n".join(lines)
