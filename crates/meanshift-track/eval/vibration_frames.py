#!/usr/bin/env python3
"""Score `track_markers` on the real vibration frames (../shared/data/tracking/vibration_frames).

The 28 targets (white squares with a black dot, 4 rows x 7 columns) are found on the first
frame by template matching; their true paths come from OpenCV template matching with a large
context template on each row's hub target (the one on the dark star connector, which no other
target resembles), refined per target with a small template near the row's shift. Then the
example runs with our tracker and with plain mean-shift (`--paper`), both with the gray model,
and this prints, for each, the share of marker-frames within 3 px of the truth (after removing
each marker's first-frame offset between the centroid and the template centre), the share
still on its own target (within 20 px; neighbours are 150 px apart) and that share over the
release (frames 229-247), and the frames reported as found (tracked or recovered) more than
8 px off. All 28 targets are tracked at once, 44x44 windows as in the issue.

With `--subsets SEED COUNT [--window PX] [--offset PX]`, it also tracks, with our tracker only, each row of 7 alone and
COUNT random selections of 7 of the 28 targets (and two of 12) drawn with SEED, as users who
select only some targets would, and prints each selection's share within 4 px and frames
found more than 8 px off, and the totals; `--window` sets those selections' window side
(default 44) and `--offset` moves each window's centre by that many pixels along both axes,
the signs alternating by marker.

Needs opencv-python-headless and numpy (not needed by CI). Run from the repository root:
    python3 crates/meanshift-track/eval/vibration_frames.py [FRAMES_DIR] [--subsets SEED COUNT
        [--window PX] [--offset PX]]
"""
import json
import math
import os
import random
import subprocess
import sys
import tempfile

import cv2

ARGS = sys.argv[1:]


def option(name, count):
    """The `count` integers after `--name` (removed from ARGS), or None."""
    if "--" + name not in ARGS:
        return None
    k = ARGS.index("--" + name)
    values = [int(v) for v in ARGS[k + 1:k + 1 + count]]
    del ARGS[k:k + 1 + count]
    return values


SUBSETS = option("subsets", 2)
SELECTION_WINDOW = (option("window", 1) or [44])[0]
SELECTION_OFFSET = (option("offset", 1) or [0])[0]
FRAMES = ARGS[0] if ARGS else "../shared/data/tracking/vibration_frames"
FIRST, LAST = 201, 260
HUB = (621, 454)  # the top row's hub target on frame 201 (pixels)
ROWS_Y = (455, 930, 1415, 1905)
WINDOW = (44, 44)
RELEASE = range(229 - FIRST, 247 - FIRST + 1)


def load(i):
    return cv2.imread(os.path.join(FRAMES, "IMG%05d.jpg" % i), cv2.IMREAD_GRAYSCALE)


def find_targets(g0):
    x, y = HUB
    small = g0[y - 22:y + 22, x - 22:x + 22]
    res = cv2.matchTemplate(g0, small, cv2.TM_CCOEFF_NORMED)
    found = []
    while True:
        _, score, _, loc = cv2.minMaxLoc(res)
        if score < 0.6:
            break
        tx, ty = loc[0] + 22, loc[1] + 22
        if min(abs(ty - ry) for ry in ROWS_Y) < 25:
            found.append((int(tx), int(ty)))
        res[max(0, loc[1] - 40):loc[1] + 40, max(0, loc[0] - 40):loc[0] + 40] = -1
    return sorted(found, key=lambda t: (t[1] // 200, t[0]))


def truth_paths(frames, targets):
    rows = {}
    for t in targets:
        rows.setdefault(t[1] // 200, []).append(t)
    truth = {}
    for r, ts in rows.items():
        hx, hy = min(ts, key=lambda t: abs(t[0] - HUB[0]))
        tpl = frames[0][hy - 60:hy + 60, hx - 60:hx + 60]
        shifts = []
        for g in frames:
            band = g[hy - 150:hy + 150, hx - 250:hx + 250]
            _, score, _, loc = cv2.minMaxLoc(cv2.matchTemplate(band, tpl, cv2.TM_CCOEFF_NORMED))
            x, y = loc[0] + hx - 250 + 60, loc[1] + hy - 150 + 60
            shifts.append((x - hx, y - hy))
            if score > 0.9:
                tpl = g[y - 60:y + 60, x - 60:x + 60]
        for tx, ty in ts:
            small = frames[0][ty - 20:ty + 20, tx - 20:tx + 20]
            path = []
            for g, (sx, sy) in zip(frames, shifts):
                gx, gy = tx + sx, ty + sy
                band = g[gy - 32:gy + 32, gx - 32:gx + 32]
                _, _, _, loc = cv2.minMaxLoc(cv2.matchTemplate(band, small, cv2.TM_CCOEFF_NORMED))
                path.append((gx - 32 + loc[0] + 20, gy - 32 + loc[1] + 20))
            truth["r%dx%d" % (r, tx)] = ((tx, ty), path)
    return truth


def score(out, truth):
    n = within = within4 = own = rel = rel_own = found_far = 0
    for m in out["markers"]:
        path = truth[m["id"]][1]
        c0 = m["centers"][0]
        bx, by = c0[0] - path[0][0], c0[1] - path[0][1]
        for i, (c, p) in enumerate(zip(m["centers"], path)):
            e = math.inf if c is None else math.hypot(c[0] - bx - p[0], c[1] - by - p[1])
            n += 1
            within += e <= 3.0
            within4 += e <= 4.0
            found_far += m["status"][i] in ("tracked", "recovered") and e > 8.0
            own += e <= 20.0
            if i in RELEASE:
                rel += 1
                rel_own += e <= 20.0
    return 100 * within / n, 100 * within4 / n, 100 * own / n, 100 * rel_own / rel, found_far, n


def init_of(truth, keys, side=WINDOW[0], offset=0):
    """Windows of `side` px centred on the targets, each centre moved by `offset` px along x
    and y, with signs alternating by marker (a user does not click exactly)."""
    return [{"id": k,
             "x": truth[k][0][0] - side // 2 + (offset if i % 2 else -offset),
             "y": truth[k][0][1] - side // 2 + (offset if i % 3 else -offset),
             "w": side, "h": side} for i, k in enumerate(keys)]


def run(init, tmp, extra=()):
    init_path = os.path.join(tmp, "init.json")
    with open(init_path, "w") as f:
        json.dump(init, f)
    out_path = os.path.join(tmp, "out.json")
    subprocess.run(["cargo", "run", "--release", "-q", "--example", "track_markers", "--",
                    FRAMES, init_path, "--model", "gray", "--out", out_path] + list(extra),
                   check=True, stderr=subprocess.DEVNULL)
    with open(out_path) as f:
        return json.load(f)


def subsets(truth, seed, count):
    keys = list(truth.keys())
    rng = random.Random(seed)
    rows = sorted({k.split("x")[0] for k in keys})
    chosen = [[k for k in keys if k.split("x")[0] == r] for r in rows]
    chosen += [sorted(rng.sample(keys, 7)) for _ in range(count)]
    chosen += [sorted(rng.sample(keys, 12)) for _ in range(2)]
    n_all = within4_all = far_all = 0
    with tempfile.TemporaryDirectory() as tmp:
        for keys in chosen:
            init = init_of(truth, keys, SELECTION_WINDOW, SELECTION_OFFSET)
            _, w4, _, _, far, n = score(run(init, tmp), truth)
            n_all += n
            within4_all += w4 * n / 100
            far_all += far
            print("  %-70s %5.1f %% within 4 px, %d found more than 8 px off"
                  % (",".join(keys), w4, far))
    print("selections (seed %d, %d of 7): %d marker-frames, %.2f %% within 4 px, %d found "
          "(tracked or recovered) more than 8 px off"
          % (seed, count, n_all, 100 * within4_all / n_all, far_all))


def main():
    frames = [load(i) for i in range(FIRST, LAST + 1)]
    targets = find_targets(frames[0])
    truth = truth_paths(frames, targets)
    if SUBSETS is not None:
        subsets(truth, *SUBSETS)
    init = init_of(truth, list(truth.keys()))
    with tempfile.TemporaryDirectory() as tmp:
        for name, extra in (("ours", []), ("plain mean-shift (--paper)", ["--paper"])):
            out = run(init, tmp, extra)
            w, w4, o, r, far, n = score(out, truth)
            print("%-28s %d marker-frames: %.1f %% within 3 px, %.1f %% within 4 px, "
                  "%.1f %% on their own target, %.1f %% over the release, %d found (tracked or "
                  "recovered) more than 8 px off; track_s %.3f"
                  % (name, n, w, w4, o, r, far, out["timing"]["track_s"]))


if __name__ == "__main__":
    main()
