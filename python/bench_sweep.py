#!/usr/bin/env python3
"""The robustness sweep on a dask.distributed LocalCluster against the command on as many threads
(docs/PERFORMANCE.md, "Sweeps in parts").

    PYTHONPATH=build/python python3 python/bench_sweep.py [--pamc build/src/pamc] [--workers 2] [ARGS...]

Runs `pamc robustness --threads W ARGS`, then pamc.sweep.robustness with the same settings on a LocalCluster
of W one-thread workers (W parts per phase), each into a folder of its own; prints both wall times, their
ratio and whether the CSVs are byte-identical. ARGS: --duration-scale S, --method M, --only-axes A,B (as the
command's; default: its full run)."""
import argparse
import filecmp
import os
import platform
import subprocess
import sys
import tempfile
import time

sys.path = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(os.path.abspath(__file__))]
import pamc.sweep  # noqa: E402
from dask.distributed import Client, LocalCluster  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pamc", default="build/src/pamc")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--duration-scale", type=float, default=1.0)
    ap.add_argument("--method", default="ga")
    ap.add_argument("--only-axes", default="")
    a = ap.parse_args()
    work = tempfile.mkdtemp(prefix="pamc_bench_sweep_")
    load = os.getloadavg()[0]
    axes = [x for x in a.only_axes.split(",") if x]
    cli = [a.pamc, "robustness", "--threads", str(a.workers), "--duration-scale", str(a.duration_scale), "--method",
           a.method, "--out-dir", os.path.join(work, "cli")] + (["--only-axes", a.only_axes] if axes else [])
    t0 = time.perf_counter()
    subprocess.run(cli, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t_cli = time.perf_counter() - t0
    with LocalCluster(n_workers=a.workers, threads_per_worker=1, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        t0 = time.perf_counter()
        pamc.sweep.robustness(os.path.join(work, "dask"), client=client, only_axes=axes, duration_scale=a.duration_scale,
                              fit_method=a.method)
        t_dask = time.perf_counter() - t0
    csvs = sorted(f for f in os.listdir(os.path.join(work, "cli")) if f.endswith(".csv"))
    same = all(filecmp.cmp(os.path.join(work, "cli", f), os.path.join(work, "dask", f), shallow=False) for f in csvs)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, load before "
          f"{load:.1f}")
    print(f"pamc robustness --threads {a.workers}: {t_cli:.1f} s")
    print(f"pamc.sweep.robustness on a LocalCluster of {a.workers} workers: {t_dask:.1f} s "
          f"({t_dask / t_cli:.2f}x); {len(csvs)} CSVs {'byte-identical' if same else 'DIFFER'}; results in {work}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
