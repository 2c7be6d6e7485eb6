#!/usr/bin/env python3
"""TreeQSM's columns of the issue 22 table: models of a cloud by TreeQSM, measured like ours.

TreeQSM itself is MATLAB; this runs PyTLiDAR (`pip install pytlidar`, 1.1.2 here), a
Python port of TreeQSM 2.4 by its users, on the cloud, keeps the model TreeQSM's own
`all_mean_dis` ranks best among the parameter sets `define_input` proposes, and measures its
cylinders by issue 22's measure (`space_colonize::fidelity`: each cylinder a cone of equal
end radii; a point's distance |distance to the axis segment - radius| over the 16 cylinders
with the nearest midpoints; "model near cloud" the share of axis length, sampled every 1 cm,
whose nearest point lies within the radius + 2 cm). That measure is re-implemented here in
numpy; on our own coffee-tree skeleton (`reconstruct_tree --out-skeleton`) it gives what
`reconstruct_tree`'s `"fidelity"` gives (2.21 mm / 99.6 % / 99.95 %).

It also measures any other model given: a skeleton JSON (`--out-skeleton`) or a cylinder
CSV with start_x..z, axis_x..z, length and radius columns (ours, or TreeQSM's published
`qsm_treeqsm_cylinders.csv`).

Not needed by CI (PyTLiDAR pulls numba and matplotlib; a run takes minutes). Usage, from the
repository root:
    python3 crates/space-colonize/eval/treeqsm_columns.py CLOUD [--sets N1 N2MIN N2MAX]
        [--inputs KEY=V[,V...] ...] [--out CYLINDERS.csv] [--measure MODEL ...]
With `--sets 0 0 0` PyTLiDAR is not run and only the `--measure` models are measured.
"""
import argparse
import csv
import json
import sys
import time

import numpy as np
from scipy.spatial import cKDTree

CANDIDATES = 16  # space_colonize::fidelity::CANDIDATE_EDGES
SAMPLE_M = 0.01  # MODEL_SAMPLE_M
NEAR_M = 0.02  # NEAR_CLOUD_M


def cones_from_skeleton(path):
    nodes = json.load(open(path))["nodes"]
    pos = np.array([n["position"] for n in nodes], float)
    rad = np.array([n["radius"] for n in nodes], float)
    edges = [(n["parent"], n["id"]) for n in nodes if n["parent"] is not None]
    p = np.array([e[0] for e in edges])
    c = np.array([e[1] for e in edges])
    a = pos[p]
    d = pos[c] - a
    length = np.linalg.norm(d, axis=1)
    ok = length > 0
    return a[ok], d[ok] / length[ok, None], length[ok], rad[p][ok], rad[c][ok]


def cones_from_csv(path):
    rows = list(csv.DictReader(open(path)))
    a = np.array([[float(r["start_" + k]) for k in "xyz"] for r in rows])
    u = np.array([[float(r["axis_" + k]) for k in "xyz"] for r in rows])
    length = np.array([float(r["length"]) for r in rows])
    radius = np.array([float(r["radius"]) for r in rows])
    ok = length > 0
    u = u[ok] / np.linalg.norm(u[ok], axis=1)[:, None]
    return a[ok], u, length[ok], radius[ok], radius[ok]


def fidelity(points, a, u, length, ra, rb):
    mids = a + u * (length / 2)[:, None]
    k = min(CANDIDATES, len(length))
    _, idx = cKDTree(mids).query(points, k=k)
    idx = idx.reshape(len(points), -1)
    best = np.full(len(points), np.inf)
    for j in range(idx.shape[1]):
        c = idx[:, j]
        v = points - a[c]
        t = np.clip((v * u[c]).sum(1), 0, length[c])
        axis = np.linalg.norm(v - u[c] * t[:, None], axis=1)
        best = np.minimum(best, np.abs(axis - (ra[c] + (rb[c] - ra[c]) * t / length[c])))
    cloud = cKDTree(points)
    near = 0.0
    for i in range(len(length)):
        n = max(1, int(np.ceil(length[i] / SAMPLE_M)))
        piece = length[i] / n
        t = (np.arange(n) + 0.5) * piece
        d, _ = cloud.query(a[i] + u[i] * t[:, None])
        near += piece * (d <= ra[i] + (rb[i] - ra[i]) * t / length[i] + NEAR_M).sum()
    return {
        "mean_distance_m": float(best.mean()),
        "within_2cm": float((best <= NEAR_M).mean()),
        "model_near_cloud": float(near / length.sum()),
        "axis_length_m": float(length.sum()),
        # Frusta (cylinders for TreeQSM); a skeleton's counts branches from their fork's
        # centre, so it is more than our cylinder table's `volume_l`.
        "cone_volume_l": float((np.pi / 3 * (ra * ra + ra * rb + rb * rb) * length).sum() * 1000),
    }


def run_treeqsm(points, sets, out, overrides):
    from PyTLidar.Utils.define_input import define_input
    from PyTLidar.treeqsm import calculate_optimal, treeqsm

    inputs = define_input(points, *sets)[0]
    for key in ("disp", "plot", "savepdf", "savemat", "savetxt"):
        inputs[key] = 0
    for item in overrides:
        key, value = item.split("=", 1)
        values = [float(v) for v in value.split(",")]
        old = inputs.get(key)
        inputs[key] = np.array(values) if isinstance(old, (list, np.ndarray)) else values[0]
    used = {k: (np.asarray(v).tolist() if isinstance(v, (list, np.ndarray)) else v)
            for k, v in inputs.items() if k.startswith(("PatchDiam", "BallRad", "nmin",
                                                        "MinCylRad", "ParentCor", "TaperCor"))}
    start = time.time()
    models, _ = treeqsm(points, inputs)
    seconds = time.time() - start
    if models == "ERROR" or not models:
        sys.exit("PyTLiDAR failed on this cloud")
    best = calculate_optimal(models, "all_mean_dis")[0] if len(models) > 1 else 0
    cyl = models[best]["cylinder"]
    start_m = np.asarray(cyl["start"], float)
    axis = np.asarray(cyl["axis"], float)
    length = np.asarray(cyl["length"], float).ravel()
    radius = np.asarray(cyl["radius"], float).ravel()
    parent = np.asarray(cyl["parent"]).ravel()
    with open(out, "w") as f:
        f.write("id,parent,start_x,start_y,start_z,axis_x,axis_y,axis_z,length,radius\n")
        for i in range(len(length)):
            f.write("%d,%d,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f\n"
                    % (i, parent[i], *start_m[i], *axis[i], length[i], radius[i]))
    return {"models": len(models), "chosen": best, "cylinders": int(len(length)),
            "seconds": seconds, "inputs": used}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cloud")
    ap.add_argument("--sets", type=int, nargs=3, default=[2, 2, 2],
                    metavar=("N1", "N2MIN", "N2MAX"),
                    help="parameter values per patch diameter for define_input (0 0 0: no run)")
    ap.add_argument("--out", default="treeqsm_cylinders.csv")
    ap.add_argument("--measure", nargs="*", default=[])
    ap.add_argument("--inputs", nargs="*", default=[], metavar="KEY=V[,V...]",
                    help="TreeQSM inputs to set after define_input, e.g. PatchDiam1=0.004")
    args = ap.parse_args()
    points = np.loadtxt(args.cloud)[:, :3].astype(float)
    report = {"cloud": args.cloud, "points": len(points)}
    models = list(args.measure)
    if any(args.sets):
        report["treeqsm"] = run_treeqsm(points, args.sets, args.out, args.inputs)
        models.insert(0, args.out)
    for path in models:
        cones = cones_from_skeleton(path) if path.endswith(".json") else cones_from_csv(path)
        report[path] = fidelity(points, *cones)
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
