#!/usr/bin/env python3
"""Wall time of the same jobs in one process and on a local Ray cluster of 1 and 2 workers
(docs/scale-out.md).

    .venv/bin/python scripts/scale_out_bench.py --scale tiny  --repeats 3 --out docs/scale-out-timings-tiny.md
    .venv/bin/python scripts/scale_out_bench.py --scale small --repeats 1 --out docs/scale-out-timings-small.md

Jobs (`tiny`: the CI sizes; `small`: the studies' real sizes):
  * tiny  — `dataset`: 16 phantoms at 16³, 8 views per rotation; `study`: `tomograf study
            realism-gap --scale tiny` (4 levels: data, train, evaluate, report);
  * small — `dataset`: 32 phantoms at 64³, 36 views (the `small` studies' training set);
            `evaluate`: the shipped demo checkpoint (the `small` model) with every baseline
            on 4 held-out `lidc` phantoms, from 1 view.
Ways: `1 process` (`tomograf --threads 1`), `1 process, 2 threads` (`--threads 2`), `Ray, 1
worker` and `Ray, 2 workers` (`ray.init(num_cpus=k)`, 1 thread per task, `tomograf.distributed`
with as many shards as workers × 2; the Ray start-up is timed apart). Every run writes into a
fresh folder; the ways are interleaved per repeat; medians are reported.
"""

import argparse
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def jobs(scale: str, work: Path):
    """name → (command builder for an output folder, setup run once)."""
    ck = str(ROOT / "model/checkpoints/demo")
    test_dir = work / "test"
    if scale == "tiny":
        data = ["--phantoms", "16", "--size", "16", "--views", "8"]
        out = {
            "dataset": lambda o: ("dataset", [o, *data]),
            "study": lambda o: ("study", ["realism-gap", o, "--scale", "tiny", "--seed", "0"]),
        }
        return out, None
    data = ["--phantoms", "32", "--size", "64", "--views", "36"]
    test = ["--phantoms", "4", "--seed", "50000", "--size", "64", "--views", "10", "--split", "test"]
    out = {
        "dataset": lambda o: ("dataset", [o, *data]),
        "evaluate": lambda o: ("evaluate", [str(test_dir), o, "--checkpoint", ck, "--views", "1", "--seed", "0"]),
    }
    return out, ["dataset", "-o", str(test_dir), *test]


def one_process(exe: str, threads: int, kind: str, args: list) -> None:
    if kind == "dataset":
        argv = ["dataset", "-o", args[0], *args[1:]]
    elif kind == "evaluate":
        argv = ["evaluate", args[0], "-o", args[1], *args[2:]]
    else:
        argv = ["study", args[0], "-o", args[1], *args[2:]]
    subprocess.run([exe, "--threads", str(threads), *argv], check=True, capture_output=True)


def with_ray(exe: str, kind: str, args: list, workers: int) -> None:
    from tomograf import distributed as td

    shards = 2 * workers
    if kind == "dataset":
        td.dataset(args[0], *args[1:], shards=shards, binary=exe, progress=None)
    elif kind == "evaluate":
        td.evaluate(args[0], args[1], *args[2:], shards=shards, binary=exe, progress=None)
    else:
        td.study(args[0], args[1], *args[2:], shards=shards, binary=exe, progress=None)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scale", choices=["tiny", "small", "medium"], default="tiny")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path, help="markdown file to write (default: print only)")
    ap.add_argument("--binary", default=os.environ.get("TOMOGRAF_BIN") or str(ROOT / "target/release/tomograf"))
    ap.add_argument("--jobs", default="", help="comma-separated subset of the jobs")
    a = ap.parse_args()
    import ray

    exe = str(Path(a.binary).resolve())
    work = Path(tempfile.mkdtemp(prefix="tomograf-scale-out-"))
    try:
        table, setup = jobs(a.scale, work)
        if setup:
            subprocess.run([exe, *setup], check=True, capture_output=True)
        names = [j for j in table if not a.jobs or j in a.jobs.split(",")]
        ways = ["1 process", "1 process, 2 threads", "Ray, 1 worker", "Ray, 2 workers"]
        times = {(j, w): [] for j in names for w in ways}
        starts = {1: [], 2: []}
        n = 0
        for rep in range(a.repeats):
            for w in ways:
                workers = 2 if w.endswith("2 workers") else 1
                if w.startswith("Ray"):
                    t0 = time.perf_counter()
                    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                             configure_logging=False)
                    starts[workers].append(time.perf_counter() - t0)
                for j in names:
                    n += 1
                    outdir = str(work / f"run{n}")
                    kind, args = table[j](outdir)
                    t0 = time.perf_counter()
                    if w.startswith("Ray"):
                        with_ray(exe, kind, args, workers)
                    else:
                        one_process(exe, 2 if "2 threads" in w else 1, kind, args)
                    dt = time.perf_counter() - t0
                    times[(j, w)].append(dt)
                    print(f"repeat {rep + 1}: {j:8s} {w:22s} {dt:8.2f} s", file=sys.stderr, flush=True)
                    shutil.rmtree(outdir, ignore_errors=True)
                if w.startswith("Ray"):
                    ray.shutdown()
        lines = [
            f"# Scale-out wall times, `{a.scale}` jobs",
            "",
            f"`.venv/bin/python scripts/scale_out_bench.py --scale {a.scale} --repeats {a.repeats}"
            + (f" --jobs {a.jobs}" if a.jobs else "")
            + f"` on "
            f"{cpu_model()} ({os.cpu_count()} CPUs), {time.strftime('%Y-%m-%d')}: median of {a.repeats} "
            "run(s) per cell, seconds of wall time (the ways interleaved per repeat). Ray: a local "
            "cluster, `tomograf.distributed` with 2 shards per worker, 1 thread per task; its "
            f"start-up (`ray.init`) took {statistics.median(starts[1]):.1f} s (1 worker) and "
            f"{statistics.median(starts[2]):.1f} s (2 workers), not included.",
            "",
            "| job | " + " | ".join(ways) + " | speed-up, Ray 2 workers vs 1 |",
            "|---|" + "---:|" * (len(ways) + 1),
        ]
        for j in names:
            med = [statistics.median(times[(j, w)]) for w in ways]
            lines.append(f"| {j} | " + " | ".join(f"{m:.2f}" for m in med) + f" | {med[2] / med[3]:.2f}× |")
        text = "\n".join(lines) + "\n"
        print(text)
        if a.out:
            a.out.write_text(text)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
