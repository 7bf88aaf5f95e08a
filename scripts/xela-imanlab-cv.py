"""Summary of scripts/xela-imanlab's leave-one-object-out folds (standard library only).

Usage: xela-imanlab-cv.py CV_DIR STATE

CV_DIR holds `sessions.tsv` (file, object, dropped) and one folder per object
with the `eval.json` of the model trained without it. Prints, beside each
other on the same steps, the dEKF, predicting no motion and the linear map:
per object and pooled over every step (sliding: position and velocity;
planar: in-plane translation and rotation), and on how many sequences the
dEKF beats each baseline.
"""
import glob
import json
import math
import os
import sys


def folds(cv):
    dropped = {}
    for line in open(os.path.join(cv, "sessions.tsv")):
        name, _, flag = line.rstrip("\n").split("\t")
        dropped[name] = flag == "true"
    rows = []
    for path in sorted(glob.glob(os.path.join(cv, "*", "eval.json"))):
        obj = os.path.basename(os.path.dirname(path))
        for s in json.load(open(path))["sessions"]:
            rows.append((obj, dropped[os.path.basename(s["file"])], s))
    return rows


def group_order(name):
    """Objects by number, then other folder names (one per trial) in order."""
    return (0, int(name), "") if name.isdigit() else (1, 0, name)


def pooled(rows, get):
    """The root of the mean squared value of `get(s)` over every step."""
    pairs = [(get(s), s["steps"]) for _, _, s in rows if get(s) is not None]
    steps = sum(n for _, n in pairs)
    return math.sqrt(sum(v * v * n for v, n in pairs) / max(steps, 1)) if pairs else float("nan")


def sliding(rows):
    get = {
        "dEKF": lambda s: s["position_rmse_cm"],
        "zero": lambda s: s["baseline_position_rmse_cm"],
        "linear": lambda s: s.get("linear_position_rmse_cm"),
    }
    print(f"{'object':>8} {'sessions':>8} {'dEKF cm':>8} {'zero cm':>8} {'linear cm':>9}")
    for obj in sorted({o for o, _, _ in rows}, key=group_order):
        part = [r for r in rows if r[0] == obj]
        print(f"{obj:>8} {len(part):>8} " + " ".join(f"{pooled(part, g):8.3f}" for g in get.values()))
    for label, flag in (("kept", False), ("dropped", True)):
        part = [r for r in rows if r[1] == flag]
        print(f"{label:>8} {len(part):>8} " + " ".join(f"{pooled(part, g):8.3f}" for g in get.values()))
    steps = sum(s["steps"] for _, _, s in rows)
    p = {k: pooled(rows, g) for k, g in get.items()}
    print(f"pooled over {steps} steps: position RMSE dEKF {p['dEKF']:.3f} cm, zero motion {p['zero']:.3f} cm, "
          f"linear map {p['linear']:.3f} cm")
    v = {
        "dEKF": pooled(rows, lambda s: s["velocity_rmse_cmps"]),
        "zero": pooled(rows, lambda s: s["baseline_velocity_rmse_cmps"]),
        "linear": pooled(rows, lambda s: s.get("linear_velocity_rmse_cmps")),
    }
    print(f"  velocity RMSE dEKF {v['dEKF']:.3f} cm/s, zero velocity {v['zero']:.3f} cm/s, "
          f"linear map {v['linear']:.3f} cm/s")
    wins = sum(1 for _, _, s in rows if s["position_rmse_cm"] < s["baseline_position_rmse_cm"])
    print(f"sequences on which the dEKF beats zero motion: {wins} of {len(rows)}")


def planar(rows):
    names = ("dekf", "zero", "linear")
    print(f"{'object':>8} {'sessions':>8} " + " ".join(f"{'T ' + n:>9}" for n in names)
          + " " + " ".join(f"{'R ' + n:>9}" for n in names))
    groups = [(o, [r for r in rows if r[0] == o]) for o in sorted({o for o, _, _ in rows}, key=group_order)]
    groups += [("kept", [r for r in rows if not r[1]]), ("dropped", [r for r in rows if r[1]])]
    for label, part in groups:
        t = [pooled(part, lambda s, n=n: (s.get(n) or {}).get("translation_rmse_mm")) for n in names]
        r = [pooled(part, lambda s, n=n: (s.get(n) or {}).get("rotation_rmse_deg")) for n in names]
        print(f"{label:>8} {len(part):>8} " + " ".join(f"{x:9.2f}" for x in t + r))
    steps = sum(s["steps"] for _, _, s in rows)
    t = {n: pooled(rows, lambda s, n=n: (s.get(n) or {}).get("translation_rmse_mm")) for n in names}
    r = {n: pooled(rows, lambda s, n=n: (s.get(n) or {}).get("rotation_rmse_deg")) for n in names}
    print(f"pooled over {steps} steps (T: in-plane translation, mm; R: rotation about the normal, deg):")
    for n in names:
        print(f"  {n:>6}: T {t[n]:6.2f} mm ({100 * t[n] / t['zero']:4.0f} % of zero), "
              f"R {r[n]:6.2f} deg ({100 * r[n] / r['zero']:4.0f} % of zero)")
    print(f"  dEKF over the linear map: T {100 * t['dekf'] / t['linear']:.0f} %, R {100 * r['dekf'] / r['linear']:.0f} %")
    for base in ("zero", "linear"):
        bt = sum(1 for _, _, s in rows if s["dekf"]["translation_rmse_mm"] < s[base]["translation_rmse_mm"])
        br = sum(1 for _, _, s in rows if s["dekf"]["rotation_rmse_deg"] < s[base]["rotation_rmse_deg"])
        both = sum(
            1 for _, _, s in rows
            if s["dekf"]["translation_rmse_mm"] < s[base]["translation_rmse_mm"]
            and s["dekf"]["rotation_rmse_deg"] < s[base]["rotation_rmse_deg"]
        )
        print(f"sequences on which the dEKF beats {base}: translation {bt}, rotation {br}, both {both} of {len(rows)}")


def main():
    cv, state = sys.argv[1], sys.argv[2]
    rows = folds(cv)
    (planar if state == "planar" else sliding)(rows)


if __name__ == "__main__":
    main()
