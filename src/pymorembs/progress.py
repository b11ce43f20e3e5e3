"""Progress bars on stderr for the slow steps (frequency sweeps, time integration, jobs).

One small abstraction over ``tqdm``: :class:`Progress` is a context manager with a label, a total
and a unit. It draws nothing unless bars are on: :func:`configure` sets the mode for the whole
process -- ``"auto"`` (the default: bars only when stderr is a terminal), ``"on"`` (always,
e.g. for logs or tests) or ``"off"`` (``--quiet``). Updates are cheap and throttled, so a bar
may be advanced once per step of a tight loop.

Line messages of the command line go through :func:`write`, which keeps an active bar intact.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, Literal, TextIO

from tqdm import tqdm

Mode = Literal["auto", "on", "off"]
MODES: tuple[str, ...] = ("auto", "on", "off")

_mode: Mode = "auto"


class _Bar(tqdm):
    """tqdm without its monitor thread (worker processes are forked while bars run)."""

    monitor_interval = 0


def configure(mode: Mode) -> None:
    """Set when bars are drawn: ``"auto"`` (stderr is a terminal), ``"on"`` or ``"off"``."""
    global _mode
    if mode not in MODES:
        raise ValueError(f"progress mode must be one of {MODES}, got {mode!r}")
    _mode = mode


def mode() -> Mode:
    """The current mode (see :func:`configure`)."""
    return _mode


@contextmanager
def settings(new_mode: Mode) -> Iterator[None]:
    """Use ``new_mode`` inside the ``with`` block, then restore the previous mode."""
    previous = _mode
    configure(new_mode)
    try:
        yield
    finally:
        configure(previous)


def enabled(stream: TextIO | None = None) -> bool:
    """Whether bars are drawn now (on ``stream``, default stderr)."""
    if _mode == "off":
        return False
    if _mode == "on":
        return True
    stream = sys.stderr if stream is None else stream
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty and isatty())
    except (ValueError, OSError):  # a closed stream
        return False


class Progress:
    """A progress bar on stderr, or nothing when bars are off.

    Parameters
    ----------
    label : str
        What is being done, e.g. ``"frequency response"``.
    total : int or None
        Number of units of the whole task, or None when the end is not known in advance (e.g.
        decided by an error estimator): the bar then counts units and shows no ETA.
    unit : str
        Name of one unit, e.g. ``"freq"`` or ``"step"``.
    every : int, optional
        Draw at most once per this many units (default: about 1 % of ``total``, or every unit
        without a total); the :meth:`update` calls in between only add to a counter.
    force : bool, optional
        Draw the bar (True) or not (False) regardless of :func:`configure`.
    delay : float
        Seconds before the bar appears, so that quick tasks draw nothing; only in the
        ``"auto"`` mode (when forced, every bar is drawn at once).

    Examples
    --------
    >>> with Progress("time integration", total=1000, unit="step") as bar:
    ...     for _ in range(1000):
    ...         bar.update()
    """

    def __init__(
        self,
        label: str,
        total: int | None,
        unit: str = "it",
        every: int | None = None,
        force: bool | None = None,
        delay: float = 0.5,
    ) -> None:
        self.label = label
        self.total = None if total is None else int(total)
        self.unit = unit
        if every is None:
            every = 1 if self.total is None else self.total // 100
        self.every = max(1, int(every))
        self._enabled = enabled() if force is None else bool(force)
        self.delay = delay if force is None and _mode == "auto" else 0.0
        self.count = 0  # units done, counted also when nothing is drawn
        self._pending = 0
        self._bar: Any = None

    @property
    def active(self) -> bool:
        """Whether a bar is drawn."""
        return self._enabled

    def __enter__(self) -> Progress:
        if self._enabled and self._bar is None:
            self._bar = _Bar(
                total=self.total,
                desc=self.label,
                unit=self.unit,
                file=sys.stderr,
                leave=False,
                dynamic_ncols=True,
                mininterval=0.2,
                delay=self.delay,
            )
        return self

    def update(self, n: int = 1) -> None:
        """Advance by ``n`` units (drawn at most every :attr:`every` units)."""
        self.count += n
        if not self._enabled:
            return
        self._pending += n
        if self._pending >= self.every:
            self._flush()

    def describe(self, text: str) -> None:
        """Show ``text`` after the bar (e.g. the current stage)."""
        if self._bar is not None:
            self._bar.set_postfix_str(text, refresh=True)

    def _flush(self) -> None:
        if self._bar is not None and self._pending:
            self._bar.update(self._pending)
        self._pending = 0

    def finish(self) -> None:
        """End the bar at the units done so far: when the work ended before its total (e.g. a
        basis exhausted before the order cap), the total shrinks to the count."""
        if self.total is None:  # a count without a total already ends with the work
            return
        self.total = min(self.total, self.count)
        if self._bar is not None:
            self._flush()
            self._bar.total = self._bar.n
            self._bar.refresh()

    def close(self) -> None:
        """Draw the remaining units and remove the bar."""
        if self._bar is not None:
            self._flush()
            self._bar.close()
            self._bar = None

    def __exit__(self, *exc: object) -> None:
        self.close()


def write(line: str, file: TextIO | None = None) -> None:
    """Print ``line`` (to stdout by default) without breaking an active progress bar."""
    file = sys.stdout if file is None else file
    tqdm.write(line, file=file)
    file.flush()


__all__ = ["MODES", "Progress", "configure", "enabled", "mode", "settings", "write"]
