"""The plain-Python logic of ``param_bridge_node`` (no ROS here): which target parameter each
space parameter sets, whether the target's parameters can take the space, and a trial's score.

A trial's score is exact by construction, not by timing (:class:`TrialWindow`). Every score
sample carries the middleware's publication stamp and the publisher's sequence number (rclpy's
``MessageInfo``), both written by the target's process when it published the sample. The
window opens at the publication stamp of the target's answer to the trial's last request (the
reset, or the parameter set when there is no reset service): a sample published before that
answer belongs to the previous trial, one published after it to this one, whatever the order
in which this node's executor takes them. It closes at the first of: ``trial_samples`` samples
(a count), the publication stamp of the done message (``done_topic``), or the window's
duration after the opening stamp. Within the window the publisher's sequence numbers must be
consecutive: a gap means samples were lost (a full queue), a step back means another
publisher (the target was restarted): the trial fails rather than score what it has.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum
from typing import Any

from localpbo_core.space import ParameterSpace
from localpbo_core.validation import SettingError

SCORE_KINDS = ("reward", "cost")
REDUCERS = ("mean", "sum", "last", "min", "max")


def target_names(space: ParameterSpace, mapping: Mapping[str, Any]) -> tuple[str, ...]:
    """The target's parameter name for each space parameter (identity unless mapped).

    Raises:
        SettingError: ``mapping.<key>`` for a key that is not a space parameter or a value
            that is not a parameter name; ``mapping`` when two map to the same target.
    """
    for key, value in mapping.items():
        if key not in space.names:
            raise SettingError(
                f"mapping.{key}", f"is not a parameter of the space ({', '.join(space.names)})"
            )
        if not isinstance(value, str) or not value:
            raise SettingError(f"mapping.{key}", f"must be a parameter name, got {value!r}")
    names = tuple(str(mapping.get(n, n)) for n in space.names)
    if len(set(names)) != len(names):
        raise SettingError("mapping", f"two space parameters set the same target: {names}")
    return names


@dataclass(frozen=True)
class TargetParameter:
    """What the target node says about one of its parameters (parameter services)."""

    name: str
    exists: bool
    is_double: bool = False
    read_only: bool = False
    ranges: tuple[tuple[float, float], ...] = ()


def check_listed(space: ParameterSpace, names: tuple[str, ...], listed: set[str]) -> None:
    """Refuse a target that lacks one of the parameters (its listing, before describing:
    the parameter services answer a description of several names with nothing at all when
    one of them is missing).

    Raises:
        SettingError: ``target.<first missing parameter>``, the others missing named too.
    """
    missing = [(p, n) for p, n in zip(space.parameters, names, strict=True) if n not in listed]
    if missing:
        p, name = missing[0]
        via = "" if name == p.name else f" (space parameter {p.name!r})"
        also = [n for _, n in missing[1:]]
        more = f"; also missing: {', '.join(also)}" if also else ""
        raise SettingError(
            f"target.{name}", f"the target node has no parameter {name!r}{via}{more}"
        )


def check_target(
    space: ParameterSpace, names: tuple[str, ...], described: Mapping[str, TargetParameter]
) -> None:
    """Refuse a target that cannot take every candidate of ``space``.

    Each target parameter must exist, be a double, be writable and (when its descriptor has
    a ``floating_point_range``) contain the space's bounds.

    Raises:
        SettingError: ``target.<target parameter>`` with the reason (space parameter named).
    """
    for p, name in zip(space.parameters, names, strict=True):
        field = f"target.{name}"
        info = described.get(name)
        via = "" if name == p.name else f" (space parameter {p.name!r})"
        if info is None or not info.exists:
            raise SettingError(field, f"the target node has no parameter {name!r}{via}")
        if not info.is_double:
            raise SettingError(field, f"is not a double parameter{via}")
        if info.read_only:
            raise SettingError(field, f"is read-only{via}")
        for lo, hi in info.ranges:
            if not lo <= p.lower <= p.upper <= hi:
                raise SettingError(
                    field,
                    f"accepts [{lo!r}, {hi!r}], the space asks for [{p.lower!r}, {p.upper!r}]{via}",
                )


class ScoreWindow:
    """Score samples of one trial, reduced to one value (a cost is negated: higher is better).

    Args:
        kind: ``reward`` (higher is better) or ``cost`` (lower is better).
        reduce: ``mean``, ``sum``, ``last``, ``min`` or ``max`` of the samples (of the raw
            samples, before a cost is negated).
    """

    def __init__(self, kind: str, reduce: str) -> None:
        if kind not in SCORE_KINDS:
            raise SettingError("score_kind", f"must be one of {SCORE_KINDS}, got {kind!r}")
        if reduce not in REDUCERS:
            raise SettingError("score_reduce", f"must be one of {REDUCERS}, got {reduce!r}")
        self.kind = kind
        self.reduce = reduce
        self.open = False
        self._clear()

    def _clear(self) -> None:
        self.count = 0
        self._sum = 0.0
        self._last = 0.0
        self._min = math.inf
        self._max = -math.inf

    def start(self) -> None:
        """Open the window (forgetting earlier samples)."""
        self._clear()
        self.open = True

    def add(self, value: float) -> bool:
        """Take a sample; False (and nothing taken) when closed or not finite."""
        if not self.open or not math.isfinite(value):
            return False
        self.count += 1
        self._sum += value
        self._last = value
        self._min = min(self._min, value)
        self._max = max(self._max, value)
        return True

    def close(self) -> float | None:
        """Close the window; the trial's score (None without samples or if not finite)."""
        self.open = False
        if not self.count:
            return None
        value = {
            "mean": self._sum / self.count,
            "sum": self._sum,
            "last": self._last,
            "min": self._min,
            "max": self._max,
        }[self.reduce]
        score = -value if self.kind == "cost" else value
        return score if math.isfinite(score) else None


class Sample(Enum):
    """What :meth:`TrialWindow.add` did with a score sample."""

    TAKEN = "taken"
    BEFORE = "before"
    """Published before the window opened (the previous trial's, or between trials)."""
    AFTER = "after"
    """Published after the window closed (proves every earlier sample has arrived)."""
    CLOSED = "closed"
    """No window is open."""
    PENDING = "pending"
    """Kept until the window's opening stamp is known (:meth:`TrialWindow.arm`)."""
    NON_FINITE = "non_finite"


class TrialWindow:
    """The score samples of one trial, selected by their publication stamps (module docstring).

    Samples are kept (stamp, sequence number, value) while the window is open, because its
    end may become known only later: a done message can be taken after samples the target
    published after it. :meth:`close` reduces those published within the window.

    Args:
        kind: ``reward`` (higher is better) or ``cost`` (lower is better).
        reduce: ``mean``, ``sum``, ``last``, ``min`` or ``max`` of the raw samples.
        samples: close after this many samples (0: no count).
        min_samples: fewer samples than this fail the trial.
        max_gap_ns: longest silence between two samples of the window, between its opening
            and its first sample, or between its last sample and a later one published after
            the window (0: no limit).
        max_kept: most samples one trial may hold (more fail it: memory stays bounded).
    """

    def __init__(
        self,
        kind: str,
        reduce: str,
        *,
        samples: int = 0,
        min_samples: int = 1,
        max_gap_ns: int = 0,
        max_kept: int = 10_000_000,
    ) -> None:
        self.scores = ScoreWindow(kind, reduce)
        self.samples = samples
        self.min_samples = max(1, min_samples, samples)
        self.max_gap_ns = max_gap_ns
        self.max_kept = max_kept
        self.open = False
        self.start_ns = 0
        self.end_ns: int | None = None
        self.failure = ""
        self._kept: list[tuple[int, int | None, float]] = []
        self._last_seq: int | None = None
        self._seq_before: int | None = None
        self._after = False

    @property
    def count(self) -> int:
        """Samples within the window so far (as far as its end is known)."""
        end = self.end_ns
        return sum(1 for stamp, _, _ in self._kept if end is None or stamp <= end)

    @property
    def complete(self) -> bool:
        """Every sample of the window has arrived: ``samples`` were counted, or one published
        after the window's end arrived (a publisher's samples arrive in order)."""
        if self.samples and len(self._kept) >= self.samples:
            return True
        return self.end_ns is not None and (
            self._after or any(stamp > self.end_ns for stamp, _, _ in self._kept[-1:])
        )

    def arm(self) -> None:
        """A trial is being set up: keep every sample from now on until :meth:`start` says
        which were published after the window opened (the node may take samples of the new
        trial before the answer that opens the window)."""
        self.open = True
        self.start_ns = -1
        self.end_ns = None
        self.failure = ""
        self._kept = []
        self._seq_before = self._last_seq
        self._after = False

    def start(self, start_ns: int, duration_ns: int | None) -> None:
        """Open the window for samples published after ``start_ns`` (and, with a duration, at
        most ``duration_ns`` later); samples kept since :meth:`arm` are sorted in or out."""
        if not self.open or self.start_ns >= 0:
            self.arm()
        kept, self._kept = self._kept, []
        self.start_ns = start_ns
        self.end_ns = None if duration_ns is None else start_ns + duration_ns
        for stamp, seq, value in kept:
            if stamp <= start_ns:
                self._seq_before = seq
            else:
                self._kept.append((stamp, seq, value))

    def end_at(self, stamp_ns: int) -> bool:
        """The trial was declared done at ``stamp_ns``: samples published later do not count.
        False (nothing changed) for a stamp before the window opened (a stale done)."""
        if not self.open or stamp_ns <= self.start_ns:
            return False
        if self.end_ns is None or stamp_ns < self.end_ns:
            self.end_ns = stamp_ns
        return True

    def add(self, value: float, stamp_ns: int, seq: int | None) -> Sample:
        """Offer a sample published at ``stamp_ns`` with publisher sequence number ``seq``."""
        self._last_seq = seq
        if not self.open:
            return Sample.CLOSED
        if self.start_ns < 0:  # armed: the opening stamp is not known yet
            if len(self._kept) >= self.max_kept:
                self.failure = f"more than {self.max_kept} score samples in one trial"
            else:
                self._kept.append((stamp_ns, seq, value))
            return Sample.PENDING
        if stamp_ns <= self.start_ns:
            self._seq_before = seq
            return Sample.BEFORE
        if self.samples and len(self._kept) >= self.samples:
            self._after = True
            return Sample.AFTER
        if self.end_ns is not None and stamp_ns > self.end_ns:
            if not self._after:  # the first one after the end: for the checks of the end
                self._kept.append((stamp_ns, seq, math.nan))
            self._after = True
            return Sample.AFTER
        if len(self._kept) >= self.max_kept:
            self.failure = f"more than {self.max_kept} score samples in one trial"
            return Sample.AFTER
        self._kept.append((stamp_ns, seq, value))
        return Sample.TAKEN if math.isfinite(value) else Sample.NON_FINITE

    def stalled(self, now_ns: int) -> bool:
        """True (and the failure set) when the window has been open for longer than
        ``max_gap_ns`` before ``now_ns`` without a sample. Silence after the first sample is
        judged when the next one arrives (a target may stop publishing at the end of its
        episode); a target that died is caught by the check after the trial."""
        if (
            self.open
            and self.start_ns >= 0
            and not self._kept
            and self.max_gap_ns
            and not self.failure
        ):
            horizon = now_ns if self.end_ns is None else min(now_ns, self.end_ns)
            if horizon - self.start_ns > self.max_gap_ns:
                self.failure = self._gap_text(horizon - self.start_ns)
        return bool(self.failure)

    def _gap_text(self, gap_ns: int) -> str:
        return (
            f"no score sample for {gap_ns / 1e9:.3f} s (max_sample_gap_s "
            f"{self.max_gap_ns / 1e9:g}): the target stalled or stopped"
        )

    def _judge(self) -> list[float]:
        """The window's values; sets ``failure`` on a gap in time or in sequence numbers."""
        end = self.end_ns
        if self.samples:
            kept = self._kept[: self.samples]
            values = [v for stamp, _, v in kept if end is None or stamp <= end]
        else:
            values = [v for stamp, _, v in self._kept if end is None or stamp <= end]
            kept = self._kept[: len(values) + 1]  # one after the end: its gap and sequence
        last_stamp, last_seq = self.start_ns, self._seq_before
        for stamp, seq, _ in kept:
            if seq is not None and last_seq is not None:
                if seq <= last_seq:
                    return self._fail(
                        f"score samples from another publisher (sequence {seq} after "
                        f"{last_seq}): the target was restarted or a second node publishes"
                    )
                if seq != last_seq + 1:
                    return self._fail(
                        f"{seq - last_seq - 1} score samples lost (sequence {last_seq} -> {seq})"
                    )
            gap = (stamp if end is None else min(stamp, end)) - last_stamp
            if self.max_gap_ns and gap > self.max_gap_ns:
                return self._fail(self._gap_text(gap))
            last_stamp, last_seq = stamp, seq
        return self._finite(values)

    def _finite(self, values: list[float]) -> list[float]:
        bad = sum(1 for v in values if not math.isfinite(v))
        if bad:
            return self._fail(f"{bad} non-finite score samples in the trial")
        return values

    def _fail(self, reason: str) -> list[float]:
        self.failure = reason
        return []

    def close(self) -> tuple[float | None, str]:
        """Close the window: ``(score, "")``, or ``(None, reason)`` when the trial failed."""
        values = [] if self.failure else self._judge()
        self.open = False
        self._kept = []
        if self.failure:
            return None, self.failure
        if len(values) < self.min_samples:
            return None, f"only {len(values)} of {self.min_samples} score samples in the trial"
        self.scores.start()
        for v in values:
            self.scores.add(v)
        score = self.scores.close()
        if score is None:
            return None, f"no finite score from {len(values)} samples"
        return score, ""
