"""Plots the collider curves of the benchmark report (docs/benchmarks/*.csv) into
docs/benchmarks/colliders.png: query throughput and fit against the voxel resolution n.

    cargo bench -p bvh_cloth_bench --bench report   # writes the CSV files
    pip install matplotlib && python3 scripts/plot_benchmarks.py
"""

import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

DATA = Path(__file__).resolve().parent.parent / "docs" / "benchmarks"
STYLE = {"bunny": "o-", "dragon": "s--"}


def rows(name):
    with open(DATA / name, newline="") as f:
        return list(csv.DictReader(f))


def by_model(table):
    models = {}
    for row in table:
        models.setdefault(row["model"], []).append(row)
    return models


def main():
    queries, fidelity = by_model(rows("queries.csv")), by_model(rows("fidelity.csv"))
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.8))

    for model, table in queries.items():
        n = [int(r["n"]) for r in table]
        for column, label, colour in [
            ("lbvh_qps", "LBVH", "tab:blue"),
            ("brute_qps", "brute force", "tab:orange"),
            ("parry_qps", "parry3d exact TriMesh", "tab:green"),
        ]:
            left.plot(n, [float(r[column]) / 1e6 for r in table], STYLE[model], color=colour, label=f"{label} ({model})")
    left.set_xscale("log", base=2)
    left.set_yscale("log")
    left.set_xlabel("voxel resolution n")
    left.set_ylabel("particle queries per second (millions, 1 thread)")
    left.set_title("Query throughput")
    left.legend(fontsize=7)
    left.grid(True, which="both", alpha=0.3)

    for model, table in fidelity.items():
        resting = [r for r in table if int(r["resting"]) > 0]
        right.plot([int(r["n"]) for r in resting], [float(r["mean_gap_mm"]) for r in resting], STYLE[model], color="tab:blue", label=f"mean air gap, resting ({model})")
        right.plot([int(r["n"]) for r in table], [float(r["deepest_mm"]) for r in table], STYLE[model], color="tab:red", label=f"deepest inside the mesh, any check ({model})")
        if table and "exact_mean_gap_mm" in table[0]:
            # Exact contact does not use n: one figure per model, drawn across.
            right.plot([int(r["n"]) for r in table], [float(r["exact_mean_gap_mm"]) for r in table], STYLE[model], color="tab:green", label=f"exact contact: mean air gap ({model})")
    right.set_xscale("log", base=2)
    right.set_yscale("symlog", linthresh=1.0)
    right.set_ylim(bottom=0)
    right.set_xlabel("voxel resolution n")
    right.set_ylabel("mm, against the exact mesh")
    right.set_title("Fit of a cloth resting on the spheres, and on the triangles")
    right.legend(fontsize=7)
    right.grid(True, which="both", alpha=0.3)

    fig.tight_layout()
    out = DATA / "colliders.png"
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
