"""Progress bars in a log: whole lines at the start, the milestones and the end."""

from __future__ import annotations

import io

from tqdm.std import tqdm as std_tqdm

from acoustic_sim.progress import MILESTONES, LogBar, progress_bar


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_log_gets_a_few_whole_lines():
    log = io.StringIO()
    bar = progress_bar(total=1000, desc="sound examples", file=log, leave=False, dynamic_ncols=True)
    assert isinstance(bar, LogBar)
    for i in range(1000):
        bar.update(1)
        bar.set_postfix(loss=f"{i:.1f}")
    bar.close()
    text = log.getvalue()
    lines = text.splitlines()
    assert "\r" not in text and text.endswith("\n")
    assert len(lines) == MILESTONES + 1  # the start, each quarter, the end (once)
    assert "0/1000" in lines[0] and "1000/1000" in lines[-1]
    assert all(line.startswith("sound examples:") for line in lines)


def test_iteration_and_unknown_totals_in_a_log():
    log = io.StringIO()
    assert sum(progress_bar(range(7), desc="episodes", file=log)) == 21
    with progress_bar(total=None, desc="blocks", file=log) as bar:
        bar.update(3)
    lines = log.getvalue().splitlines()
    assert lines[0].startswith("episodes:") and "7/7" in lines[-3]
    assert lines[-2].startswith("blocks: 0it") and lines[-1].startswith("blocks: 3it")
    assert "\r" not in log.getvalue()


def test_a_terminal_gets_tqdm_and_disabled_bars_write_nothing():
    term = _Terminal()
    bar = progress_bar(total=10, file=term)
    assert not isinstance(bar, LogBar) and isinstance(bar, std_tqdm)
    bar.close()
    log = io.StringIO()
    bar = progress_bar(total=10, file=log, disable=True)
    bar.update(10)
    bar.close()
    assert log.getvalue() == ""
