#!/usr/bin/env python3
"""Replays a `carla-gs run` case's `scenario.xosc` in esmini (a reference OpenSCENARIO player) and
compares what esmini moved with the case's `executed.json`: the ego's and the adversary's box
centres and headings at every esmini step, on the log's clock (OpenSCENARIO time 0 is the first
control step, `executed.steps[0].t`), and esmini's first contact of the two with the case's own.
Prints one JSON object and exits 1 when esmini fails, reports an error, a pose differs by more than
the tolerances (--max-pos-m, --max-heading-rad), or the first contacts differ by more than a step.

  python3 tools/esmini-replay.py <esmini binary> <run dir> [--dt 0.05] [--keep <dir>]

esmini is not a dependency of carla-gs: build it once from its sources (docs/export.md, "Replay in
esmini") and point this script at the binary. Standard library only.
"""
import argparse
import bisect
import csv
import json
import math
import os
import subprocess
import sys
import tempfile


def interp(path, t):
    """(x, y, heading) of a list of dicts with t, x, y, heading at time t (clamped at the ends)."""
    times = [p["t"] for p in path]
    i = bisect.bisect_left(times, t)
    if i <= 0:
        p = path[0]
        return p["x"], p["y"], p["heading"]
    if i >= len(path):
        p = path[-1]
        return p["x"], p["y"], p["heading"]
    a, b = path[i - 1], path[i]
    f = (t - a["t"]) / (b["t"] - a["t"]) if b["t"] > a["t"] else 0.0
    dh = math.atan2(math.sin(b["heading"] - a["heading"]), math.cos(b["heading"] - a["heading"]))
    return a["x"] + f * (b["x"] - a["x"]), a["y"] + f * (b["y"] - a["y"]), a["heading"] + f * dh


def read_csv(path):
    """esmini's csv_logger file: {entity name: [(t, box centre x, y, h)]} and the collisions it
    logged (entity name, the ids it collided with, time)."""
    with open(path, newline="") as f:
        lines = f.read().splitlines()
    start = next(i for i, l in enumerate(lines) if l.startswith("Index [-]"))
    header = [h.strip() for h in lines[start].split(",")]
    col = {h: k for k, h in enumerate(header) if h}
    tracks, collisions = {}, set()
    for row in csv.reader(lines[start + 1 :]):
        row = [r.strip() for r in row]
        if len(row) < 3:
            continue
        t = float(row[col["TimeStamp [s]"]])
        n = 1
        while f"#{n} Entity_Name [-]" in col:
            name_k = col[f"#{n} Entity_Name [-]"]
            if name_k >= len(row) or not row[name_k]:
                break
            get = lambda key: float(row[col[f"#{n} {key}"]])
            name = row[name_k]
            # esmini logs the reference point; the box centre is (bb_x, bb_y) from it.
            h, bx, by = get("World_Heading_Angle [rad]"), get("bb_x [m]"), get("bb_y [m]")
            x = get("World_Position_X [m]") + math.cos(h) * bx - math.sin(h) * by
            y = get("World_Position_Y [m]") + math.sin(h) * bx + math.cos(h) * by
            tracks.setdefault(name, []).append((t, x, y, h))
            ck = col.get(f"#{n} collision_ids")
            if ck is not None and ck < len(row) and row[ck] not in ("", "-1"):
                collisions.add((name, row[ck], round(t, 3)))
            n += 1
    return tracks, sorted(collisions)


def compare(esmini_track, path, t_start):
    """Largest position and heading differences of esmini's samples against `path`."""
    worst_pos, worst_h, at = 0.0, 0.0, None
    end = path[-1]["t"] - t_start
    for t, x, y, h in esmini_track:
        if t > end + 1e-6:
            break
        ex, ey, eh = interp(path, t_start + t)
        d = math.hypot(x - ex, y - ey)
        dh = abs(math.atan2(math.sin(h - eh), math.cos(h - eh)))
        if d > worst_pos:
            worst_pos, at = d, t
        worst_h = max(worst_h, dh)
    return worst_pos, worst_h, at


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("esmini")
    ap.add_argument("run_dir")
    ap.add_argument("--dt", type=float, default=0.05, help="esmini's fixed time step (s)")
    ap.add_argument("--max-pos-m", type=float, default=0.05)
    ap.add_argument("--max-heading-rad", type=float, default=0.02,
                    help="esmini interpolates headings its own way between vertices: 0.015 rad seen at 0.05 s steps")
    ap.add_argument("--keep", help="keep esmini's log and CSV in this directory")
    ap.add_argument("--traj-filter", type=float, default=0.0,
                    help="esmini's --traj_filter radius (m); its default 0.1 merges vertices closer than that, "
                    "so a creeping ego stands still, then jumps; 0 replays every vertex")
    a = ap.parse_args()
    xosc = os.path.abspath(os.path.join(a.run_dir, "scenario.xosc"))
    with open(os.path.join(a.run_dir, "executed.json")) as f:
        ex = json.load(f)
    t_start = ex["steps"][0]["t"]
    if a.keep:
        os.makedirs(a.keep, exist_ok=True)
        return replay(a, xosc, ex, t_start, a.keep)
    with tempfile.TemporaryDirectory(prefix="esmini-replay-") as work:
        return replay(a, xosc, ex, t_start, work)


def replay(a, xosc, ex, t_start, work):
    """Runs esmini in `work` and prints the report; 0 when it passes."""
    csv_path = os.path.join(work, "esmini.csv")
    cmd = [a.esmini, "--headless", "--osc", xosc, "--fixed_timestep", str(a.dt), "--csv_logger", csv_path,
           "--logfile_path", os.path.join(work, "esmini.log"), "--collision", "--traj_filter", str(a.traj_filter)]
    p = subprocess.run(cmd, cwd=work, capture_output=True, text=True, timeout=600)
    out = p.stdout + p.stderr
    errors = [l for l in out.splitlines() if "error" in l.lower() or "failed" in l.lower()]
    report = {"xosc": xosc, "esmini_rc": p.returncode, "esmini_errors": errors[:20]}
    if p.returncode != 0 or not os.path.exists(csv_path):
        report["esmini_output_tail"] = out[-3000:]
        print(json.dumps(report, indent=1))
        return 1
    tracks, collisions = read_csv(csv_path)
    ego = [{"t": s["t"], "x": s["x"], "y": s["y"], "heading": s["heading"]} for s in ex["ego_path"]]
    adv = [{"t": s["t"], "x": s["x"], "y": s["y"], "heading": s["heading"]} for s in ex["steps"]]
    ok = not errors
    report["entities"] = len(tracks)
    # Collisions esmini saw (entity name, the ids it logged); those of the ego or the adversary
    # are allowed only where the case itself has a first contact.
    report["esmini_collisions"] = sorted({(c[0], c[1]) for c in collisions})[:20]
    ours = [c for c in collisions if c[0] in ("ego", "adversary")]
    report["ego_or_adversary_collisions"] = ours[:20]
    # esmini's first ego-adversary contact (the ids are esmini's: the ego is 0, the adversary 1,
    # as the file lists them first) against the case's, which the rollout finds between steps.
    esmini_first = min((c[2] for c in collisions if c[0] == "ego" and "1" in c[1].split()), default=None)
    fc = ex.get("first_contact")
    case_first = fc["t"] - t_start if fc and fc.get("other") == "ego" else None
    report["first_contact_s"] = {"esmini": esmini_first, "case": case_first}
    if (esmini_first is None) != (case_first is None):
        ok = False
    elif esmini_first is not None and abs(esmini_first - case_first) > a.dt + 1e-6:
        ok = False
    for name, path in (("ego", ego), ("adversary", adv)):
        if name not in tracks:
            report[name] = "missing from esmini's log"
            ok = False
            continue
        pos, head, at = compare(tracks[name], path, t_start)
        report[name] = {"samples": len(tracks[name]), "max_position_error_m": pos, "at_s": at,
                        "max_heading_error_rad": head}
        ok &= pos <= a.max_pos_m and head <= a.max_heading_rad
    report["ok"] = ok
    print(json.dumps(report, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
