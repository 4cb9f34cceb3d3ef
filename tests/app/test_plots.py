"""The figures (issue 32 row 9, issue 31 figures): written atomically, nothing cut off at the edges,
lines broken where cycles are missing, the cycles the table scores shaded in the errors figure."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
from pathlib import Path

import matplotlib
import numpy as np
import pytest

from app import plots
from app.evaluation.traces import CycleTrace, RunTrace, TrackPoint

matplotlib.use("Agg")
WALLS = (((0.0, -2.45), (8.0, -2.45)), ((8.0, -2.45), (8.0, 2.45)), ((0.0, 2.45), (8.0, 2.45)))


def trace(label: str, times: list[float], scored: tuple[float, float] | None = (1.0, 2.0)) -> RunTrace:
    """A robot driving along x at 0.2 m/s and an obstacle crossing ahead, an estimate 2 cm off it."""
    cycles = []
    for t in times:
        ox, oy = 4.0 + 0.1 * t, -1.0 + 0.1 * t
        scan = np.column_stack((np.full(50, 8.0), np.linspace(-2.4, 2.4, 50)))
        views = () if scored is None else (scored[0] <= t <= scored[1],)
        cycles.append(CycleTrace(t, (0.2 * t, 0.0, 0.0), (0.2 * t + 0.01, 0.0, 0.0), scan,
                                 (TrackPoint(1, ox + 0.02, oy, 0.1, 0.1, 0.4),), ((ox, oy, 0.4),),
                                 np.zeros((0, 2)), views))
    return RunTrace(label, tuple(cycles), WALLS)


def traces(times: list[float], scored: tuple[float, float] | None = (1.0, 2.0)) -> list[RunTrace]:
    return [trace("vipsm", times, scored), trace("plain_psm", times, scored)]


TIMES = [round(0.1 * k, 1) for k in range(31)]


@pytest.mark.parametrize("figure", ["fig8", "fig9", "fig_errors"])
def test_every_label_and_title_lies_inside_the_figure(figure: str) -> None:
    fig = plots.fig8(traces(TIMES), "t", False) if figure == "fig8" else getattr(plots, figure)(traces(TIMES), "t")
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    texts = [t for ax in fig.axes for t in (ax.xaxis.label, ax.yaxis.label, ax.title) if t.get_text()]
    texts += [lg for lg in fig.legends] + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    texts.append(fig._suptitle)
    top = fig._suptitle.get_window_extent(renderer).y0
    assert all(ax.title.get_window_extent(renderer).y1 <= top + 1 for ax in fig.axes), "the title overlaps a panel's"
    if fig.legends:  # a legend below the panels: under every x label
        under = fig.legends[0].get_window_extent(renderer).y1
        assert all(ax.xaxis.label.get_window_extent(renderer).y0 >= under - 1 for ax in fig.axes if ax.get_xlabel())
    for t in texts:
        ext = t.get_window_extent(renderer)
        assert box.x0 - 1 <= ext.x0 and ext.x1 <= box.x1 + 1 and box.y0 - 1 <= ext.y0 and ext.y1 <= box.y1 + 1, \
            f"{figure}: {getattr(t, 'get_text', lambda: 'legend')()!r} is cut off: {ext} outside {box}"
    plots._plt().close(fig)


def test_lines_break_where_cycles_are_missing() -> None:
    times = [t for t in TIMES if not 1.2 < t < 1.8]  # five cycles missing
    fig = plots.fig_errors(traces(times), "gap")
    for ax in fig.axes:
        for line in ax.get_lines():
            x = np.asarray(line.get_xdata(), dtype=float)
            y = np.asarray(line.get_ydata(), dtype=float)
            finite = np.isfinite(x) & np.isfinite(y)
            # no segment is drawn across the gap: consecutive finite points are at most 1.5 steps apart
            xs = np.where(finite, x, np.nan)
            steps = np.diff(xs)
            assert not np.any(steps[np.isfinite(steps)] > 0.15 + 1e-9), f"{ax.get_ylabel()}: a line joins the gap"
    plots._plt().close(fig)


def test_the_errors_figure_shades_the_cycles_the_table_scores() -> None:
    fig = plots.fig_errors(traces(TIMES, scored=(1.0, 2.0)), "shade")
    ax = fig.axes[0]
    spans = [p for p in ax.patches if p.get_label() == "scored in the table"]
    assert len(spans) == 1
    x0, x1 = spans[0].get_x(), spans[0].get_x() + spans[0].get_width()
    assert math.isclose(x0, 0.95, abs_tol=1e-6) and math.isclose(x1, 2.05, abs_tol=1e-6)
    assert "shaded" in fig._suptitle.get_text()
    plots._plt().close(fig)
    gappy = [t for t in TIMES if not 1.2 < t < 1.8]  # cycles missing inside the scored interval: two spans
    fig = plots.fig_errors(traces(gappy, scored=(1.0, 2.0)), "gap")
    spans = sorted((p.get_x(), p.get_x() + p.get_width()) for p in fig.axes[0].patches)
    assert len(spans) == 2 and spans[0][1] == pytest.approx(1.25) and spans[1][0] == pytest.approx(1.75)
    plots._plt().close(fig)
    fig = plots.fig_errors(traces(TIMES, scored=None), "unknown")  # a real log: nothing to shade, not claimed
    assert not fig.axes[0].patches and "shaded" not in fig._suptitle.get_text()
    plots._plt().close(fig)


def test_runs_and_gaps_helpers() -> None:
    assert plots.runs(np.array([0, 1, 1, 0, 1], bool)) == [(1, 3), (4, 5)]
    assert plots.runs(np.array([], bool)) == []
    t, y = plots.with_gaps(np.array([0.0, 0.1, 0.2, 0.6, 0.7]), np.array([1.0, 2, 3, 4, 5]))
    assert np.isnan(t[3]) and np.isnan(y[3]) and len(t) == 6


def _valid_png(path: Path) -> bool:
    data = path.read_bytes()
    return data.startswith(b"\x89PNG\r\n\x1a\n") and data.endswith(b"IEND\xaeB`\x82")


def test_a_killed_figure_writer_leaves_the_old_figure_or_none_never_a_broken_one(tmp_path: Path) -> None:
    out = tmp_path / "figs"
    script = textwrap.dedent(f"""
        import os, signal, sys
        from pathlib import Path
        sys.path.insert(0, {str(Path(__file__).resolve().parents[2])!r})
        from matplotlib.figure import Figure
        from app import plots
        from tests.app.test_plots import traces, TIMES
        out = Path({str(out)!r})
        plots.write_figures(traces(TIMES), out, "run")  # a first, complete set
        def dying(self, fname, *a, **k):
            f = fname if hasattr(fname, "write") else open(fname, "wb")
            f.write(b"\\x89PNG\\r\\n\\x1a\\n half a figure")
            f.flush()
            os.kill(os.getpid(), signal.SIGKILL)
        Figure.savefig = dying
        plots.write_figures(traces(TIMES), out, "run")
        """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert proc.returncode == -9, proc.stderr
    finals = sorted(out.glob("*.png"))
    assert len(finals) == 3 and all(_valid_png(p) for p in finals), "a figure was left half written"
    assert list(out.glob(".*.partial")), "the killed writer's temporary file should be there to clean"
    plots.write_figures(traces(TIMES), out, "run")
    assert not list(out.glob(".*.partial")) and all(_valid_png(p) for p in out.glob("*.png"))
