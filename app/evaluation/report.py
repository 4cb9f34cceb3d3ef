"""The human-readable table of an evaluation, each target marked met or missed."""

from __future__ import annotations

from typing import Any

from .metrics import target_misses


# ---------------------------------------------------------------------------------------- CLI
def _fmt(x: float | None, unit_scale: float = 1.0, digits: int = 3) -> str:
    return "-" if x is None else f"{x * unit_scale:.{digits}f}"


def print_table(results: list[dict[str, Any]], factor: float = 1.0) -> None:
    """Both methods per scenario; the VIPSM row marks every target that applies met or MISSED."""
    print("Obstacle position error (Table 1 of the paper; people: against the body centre), false moving obstacles,")
    print("false safety stops, robot final pose error, obstacle velocity error (tracks older than 1 s)")
    header = (
        f"{'scenario':<24} {'method':<9} {'cyc':>4} {'err mean':>8} {'median':>7} {'std':>6} {'max':>6} "
        f"{'located':>7} {'vel err':>7} {'false/min':>9} {'stops':>5} {'false':>5} {'pose m':>6} {'head deg':>8} "
        f"{'ms/cyc':>6}  targets"
    )
    print(header)
    print("-" * len(header))
    for r in results:
        for method in ("vipsm", "plain_psm"):
            m = r[method]
            check = ""
            if method == "vipsm":
                misses = r.get("targets_missed") if factor == 1 else target_misses(m, factor)
                check = "met" if not misses else "MISSED: " + ", ".join(misses)
                check += f" (x{factor:g})" if factor != 1 else ""
            print(
                f"{r['name']:<24} {('VIPSM' if method == 'vipsm' else 'plain PSM'):<9} {r['cycles']:>4} "
                f"{_fmt(m['obstacle_err_mean_m']):>8} {_fmt(m['obstacle_err_median_m']):>7} "
                f"{_fmt(m['obstacle_err_std_m']):>6} {_fmt(m['obstacle_err_max_m'], 1, 2):>6} "
                f"{_fmt(m['obstacle_detected_fraction'], 100, 1) + '%':>7} {_fmt(m['velocity_err_mean_mps']):>7} "
                f"{_fmt(m['false_tracks_per_min'], 1, 1):>9} {m['stop_cycles']:>5} {m['false_stop_cycles']:>5} "
                f"{_fmt(m['pose_err_final_m']):>6} {_fmt(m['heading_err_final_deg'], 1, 2):>8} "
                f"{_fmt(m['ms_per_cycle'], 1, 1):>6}  {check}"
            )


def print_people_table(results: list[dict[str, Any]]) -> None:
    """Issue 29's per-person figures (VIPSM) of every scenario checked against issue 29's targets."""
    rows = [r for r in results if r.get("params", {}).get("targets") == "issue29" and r["vipsm"].get("people")]
    if not rows:
        return
    print()
    print("Per person (VIPSM; in view: >= 5 laser beams on the legs): located by people / by moving obstacles "
          "while walking,")
    print("error (people / moving obstacles), velocity error, first report after each walk start, "
          "cycles reported moving while standing > 0.5 s, people id switches")
    header = (f"{'scenario':<16} {'person':>6} {'view':>5} {'walk':>5} {'located':>7} {'moving':>7} {'err':>6} "
              f"{'err mov':>7} {'vel err':>7} {'stand':>5} {'ids':>3}  first report (s)")
    print(header)
    print("-" * len(header))
    for r in rows:
        for p in r["vipsm"]["people"]:
            first = ", ".join("never" if d is None else f"{d:.1f}" for d in p["first_report_s"]) or "-"
            located = _fmt(p["located_fraction"], 100, 1) + "%"
            moving = _fmt(p["located_moving_fraction"], 100, 1) + "%"
            print(f"{r['name']:<16} {p['index']:>6} {p['cycles_in_view']:>5} {p['cycles_walking_in_view']:>5} "
                  f"{located:>7} {moving:>7} "
                  f"{_fmt(p['err_mean_m']):>6} {_fmt(p['moving_err_mean_m']):>7} {_fmt(p['velocity_err_mean_mps']):>7} "
                  f"{p['moving_while_standing_cycles']:>5} {p['id_switches']:>3}  {first}")
