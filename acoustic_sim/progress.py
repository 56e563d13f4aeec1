"""Progress bars that suit where they are written: tqdm on a terminal, whole lines in a log.

A tqdm bar redraws itself with carriage returns; written to a file or a pipe (CI, ``make demo
2>log``) that is hundreds of updates on one line. :func:`progress_bar` gives tqdm's bar when the
stream is a terminal, and otherwise :class:`LogBar`: one line at the start, one at each
quarter of the total and one at the end, each a complete tqdm status line.
"""

from __future__ import annotations

import sys

from tqdm.auto import tqdm
from tqdm.std import tqdm as std_tqdm

MILESTONES = 4
"""A log gets a line each time another 1/MILESTONES of the total is done."""


class LogBar(std_tqdm):
    """tqdm that writes whole lines: at the start, at each milestone and at the end."""

    def __init__(self, *args, **kwargs):
        kwargs.update(mininterval=0.0, miniters=1, dynamic_ncols=False, ncols=100, ascii=True)
        self._printed: set[object] = set()
        super().__init__(*args, **kwargs)

    def _line(self, key: object) -> None:
        if key in self._printed:
            return
        self._printed.add(key)
        self.fp.write(self.__str__() + "\n")
        self.fp.flush()

    def display(self, msg=None, pos=None):  # tqdm calls this after each update
        if self.disable:
            return True
        if self.n == 0:
            self._line("start")
        elif self.total:
            step = int(MILESTONES * min(self.n, self.total) / self.total)
            if step > 0:
                self._line(step if step < MILESTONES else "end")
        return True

    def close(self):
        if not self.disable:
            self._line("end")
            self.fp = _Silent()  # the lines stay: nothing for tqdm to clear or finish
        super().close()


class _Silent:
    def write(self, _text) -> None:
        pass

    def flush(self) -> None:
        pass


def is_terminal(stream) -> bool:
    """Whether ``stream`` is an interactive terminal."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def progress_bar(iterable=None, **kwargs):
    """A tqdm progress bar (same arguments): tqdm's own on a terminal, :class:`LogBar` elsewhere."""
    stream = kwargs.get("file") or sys.stderr
    if kwargs.get("disable") or is_terminal(stream):
        return tqdm(iterable, **kwargs)
    return LogBar(iterable, **kwargs)
