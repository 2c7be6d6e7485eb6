#!/usr/bin/env python3
"""Our tracker, OpenCV's meanShift and OpenCV's CamShift side by side on the stress sequences.

For each condition and seed, `stress_export` writes the sequence (frames, first-frame windows,
truth and visibility); `track_markers` tracks it with our default tracker (hue model); OpenCV
tracks it the way the paper and OpenCV's CamShift sample do (a 16-bin hue histogram of the
first window under the mask S >= 60, V >= 32, whole-frame back-projection, then meanShift or
CamShift with 10 iterations / 1 px). All three are scored the same way as
`meanshift_track::stress::score_stress`: the share of fully visible marker-frames (frame 0
excluded) within 3 px of the truth, the longest run of fully visible frames not within 3 px,
identity swaps (a centre within 3 px of another marker's truth and not of its own), and frames
reported found more than 8 px off (OpenCV reports every frame as found).

Timing per marker-frame: ours is `track_markers`' `track_s` (everything the tracker does,
decoding excluded) over the marker-frames; OpenCV's is calcBackProject + meanShift per marker
and frame on the same frames, the HSV conversion excluded (the issue's yardstick), one thread.

Not run by CI. Needs opencv-python-headless and numpy. From the repository root:
    python3 crates/meanshift-track/eval/stress_opencv.py [--seeds 1000..1004] [--conditions a,b]
        [--model hue|hs|rgb] [--repeats N]
"""
import argparse
import json
import math
import os
import shutil
import subprocess
import tempfile
import time

import cv2
import numpy as np

CONDITIONS = ["baseline", "blur", "jumps", "reentry", "occlusion", "crossing", "flicker", "jpeg",
              "fps15", "fps60", "fps240", "release240", "kinect", "lookalikes", "combined"]
TOLERANCE_PX = 3.0
FALSE_PX = 8.0
CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 1)


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def opencv_tracks(frames, inits, camshift):
    """Centres per marker and frame, and the seconds spent in calcBackProject + the tracker."""
    hsv0 = cv2.cvtColor(frames[0], cv2.COLOR_BGR2HSV)
    mask0 = cv2.inRange(hsv0, np.array([0, 60, 32]), np.array([180, 255, 255]))
    hists, windows, centres = [], [], []
    for w in inits:
        x, y, ww, hh = w["x"], w["y"], w["w"], w["h"]
        hist = cv2.calcHist([hsv0[y:y + hh, x:x + ww]], [0], mask0[y:y + hh, x:x + ww], [16],
                            [0, 180])
        cv2.normalize(hist, hist, 0, 255, cv2.NORM_MINMAX)
        hists.append(hist)
        windows.append((x, y, ww, hh))
        centres.append([(x + ww / 2.0, y + hh / 2.0)])
    spent = 0.0
    for frame in frames[1:]:
        hsv = cv2.cvtColor(frame, cv2.COLOR_BGR2HSV)
        for k, hist in enumerate(hists):
            t = time.perf_counter()
            prob = cv2.calcBackProject([hsv], [0], hist, [0, 180], 1)
            if camshift:
                box, win = cv2.CamShift(prob, windows[k], CRITERIA)
            else:
                _, win = cv2.meanShift(prob, windows[k], CRITERIA)
            spent += time.perf_counter() - t
            if win[2] <= 0 or win[3] <= 0:  # CamShift collapsed: keep the last window
                win = windows[k]
            windows[k] = tuple(int(v) for v in win)
            if camshift:
                centres[k].append((box[0][0], box[0][1]))
            else:
                centres[k].append((win[0] + win[2] / 2.0, win[1] + win[3] / 2.0))
    return centres, spent


def score(centres, found, truth, visibility, fully):
    """As score_stress: (visible, within, longest loss, swaps, false found)."""
    visible = within = longest = swaps = false_found = 0
    markers = len(truth[0])
    runs = [0] * markers
    for f in range(len(truth)):
        for i in range(markers):
            c = centres[i][f]
            t = truth[f][i]
            err = math.inf if c is None else math.hypot(c[0] - t[0], c[1] - t[1])
            if found[i][f] and err > FALSE_PX:
                false_found += 1
            held = err <= TOLERANCE_PX
            if c is not None and not held and any(
                    j != i and math.hypot(c[0] - truth[f][j][0], c[1] - truth[f][j][1])
                    <= TOLERANCE_PX for j in range(markers)):
                swaps += 1
            if f == 0:
                continue
            if held:
                runs[i] = 0
            elif visibility[f][i] >= fully:
                runs[i] += 1
                longest = max(longest, runs[i])
            if visibility[f][i] >= fully:
                visible += 1
                within += held
    return [visible, within, longest, swaps, false_found]


def merge(total, s):
    return [total[0] + s[0], total[1] + s[1], max(total[2], s[2]), total[3] + s[3],
            total[4] + s[4]]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", default="1000..1004",
                        help="evaluation seeds, a..b (default 1000..1004; tuning seeds are 0..8)")
    parser.add_argument("--conditions", default=",".join(CONDITIONS))
    parser.add_argument("--repeats", type=int, default=1,
                        help="time each tracker this many times per sequence and keep the least"
                             " (both sides alike; a shared or noisy machine's interruptions only"
                             " ever add time; default 1)")
    parser.add_argument("--model", default="hue",
                        help="our tracker's appearance model, track_markers --model (default hue;"
                             " OpenCV's columns are the hue histogram's whatever it is)")
    args = parser.parse_args()
    a, b = (int(v) for v in args.seeds.split(".."))
    if args.repeats < 1:
        parser.error("--repeats must be at least 1")
    cv2.setNumThreads(1)
    run(["cargo", "build", "--release", "-q", "-p", "meanshift-track", "--example",
         "stress_export"])
    run(["cargo", "build", "--release", "-q", "--example", "track_markers"])
    target = os.environ.get("CARGO_TARGET_DIR", "target")
    export = os.path.join(target, "release", "examples", "stress_export")
    track = os.path.join(target, "release", "examples", "track_markers")
    print("| condition | ours: within 3 px / longest loss / swaps / false found | "
          "OpenCV meanShift | OpenCV CamShift | µs per marker-frame: ours / OpenCV "
          "calcBackProject+meanShift (ratio) |")
    print("| --- | --- | --- | --- | --- |")
    for name in args.conditions.split(","):
        totals = {k: [0, 0, 0, 0, 0] for k in ("ours", "meanshift", "camshift")}
        ours_s = ocv_s = 0.0
        marker_frames = 0
        for seed in range(a, b):
            tmp = tempfile.mkdtemp(prefix="stress_")
            try:
                run([export, tmp, name, str(seed)])
                with open(os.path.join(tmp, "truth.json")) as f:
                    rec = json.load(f)
                with open(os.path.join(tmp, "init.json")) as f:
                    inits = json.load(f)
                out = os.path.join(tmp, "ours.json")
                least_s = math.inf
                for _ in range(args.repeats):
                    run([track, tmp, os.path.join(tmp, "init.json"), "--out", out, "--model",
                         args.model])
                    with open(out) as f:
                        ours = json.load(f)
                    least_s = min(least_s, ours["timing"]["track_s"])
                truth, vis, fully = rec["truth"], rec["visibility"], rec["fully_visible"]
                n = len(truth)
                marker_frames += (n - 1) * len(inits)
                ours_s += least_s
                centres = [m["centers"] for m in ours["markers"]]
                found = [[s in ("tracked", "recovered", "set") for s in m["status"]]
                         for m in ours["markers"]]
                totals["ours"] = merge(totals["ours"], score(centres, found, truth, vis, fully))
                frames = [cv2.imread(os.path.join(tmp, "f%04d.png" % k)) for k in range(n)]
                all_found = [[True] * n for _ in inits]
                for key, cam in (("meanshift", False), ("camshift", True)):
                    c, spent = opencv_tracks(frames, inits, cam)
                    if not cam:
                        for _ in range(args.repeats - 1):
                            spent = min(spent, opencv_tracks(frames, inits, cam)[1])
                        ocv_s += spent
                    totals[key] = merge(totals[key], score(c, all_found, truth, vis, fully))
            finally:
                shutil.rmtree(tmp, ignore_errors=True)

        def cell(t):
            return "%.1f %% / %d / %d / %d" % (100.0 * t[1] / max(t[0], 1), t[2], t[3], t[4])

        ours_us = 1e6 * ours_s / marker_frames
        ocv_us = 1e6 * ocv_s / marker_frames
        print("| %s | %s | %s | %s | %.1f / %.1f (%.2fx) |" % (
            name, cell(totals["ours"]), cell(totals["meanshift"]), cell(totals["camshift"]),
            ours_us, ocv_us, ours_us / ocv_us), flush=True)


if __name__ == "__main__":
    main()
