"""Sharded tomograf jobs on a Ray cluster: data sets, evaluations and whole studies.

The command line already splits its long jobs into shards (``--shard I/N``), resumes them
(finished items are skipped; every file is written under a temporary name and renamed)
and merges them. This module deals those shards out as Ray tasks, one ``tomograf``
process per shard, and adds what a cluster needs:

* **retries**: a shard whose process or Ray worker was killed (a signal, the OOM killer,
  a lost node) is run again, up to ``max_retries`` times, and resumes where it stopped,
  so a killed worker costs only the item it was making. A shard that *fails* (the
  command exits with an error message, e.g. a bad argument or a corrupt input) is not
  retried: its error is raised once every other shard has finished;
* **no orphans**: each ``tomograf`` process dies with the Ray worker that started it, so a
  retry never races a leftover process over the same files;
* **resumption**: calling the same function again after an interruption (a failed
  shard, a killed driver) redoes only the unfinished work;
* **progress**: ``progress`` is called as each shard finishes (default: a line on stderr);
* **same bytes** as the one-process command (tested in ``bridge/tests/test_distributed.py``;
  evaluations differ only in their wall-clock ``seconds``).

Every task runs the installed command line (``binary``, else ``$TOMOGRAF_BIN``, else
``tomograf`` on ``PATH``) on every node, and every node must see the output folder at the
same path (a shared file system). Ray is an optional dependency
(``pip install ./bridge[ray]``); nothing else in the package imports it. Call
``ray.init(...)`` first to join a cluster; otherwise the first call starts a local one.

Example (a data set in 8 shards, then its evaluation in 8)::

    import ray
    from tomograf import distributed as td

    ray.init(address="auto")
    td.dataset("/shared/train", "--phantoms", "256", "--size", "64", shards=8, threads=4)
    td.evaluate("/shared/test", "/shared/eval", "--checkpoint", "/shared/run/checkpoint",
                shards=8, threads=4)
    td.study("realism-gap", "/shared/studies/r", "--scale", "small", shards=16, threads=4)

See docs/scale-out.md.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence, Union

__all__ = [
    "ShardFailed",
    "ShardKilled",
    "ShardResult",
    "print_progress",
    "find_binary",
    "run_shards",
    "run_once",
    "dataset",
    "evaluate",
    "study",
]

PathLike = Union[str, "os.PathLike[str]"]


class ShardFailed(RuntimeError):
    """A shard's command exited with an error (not retried: running it again would fail
    the same way). The message holds the command and the end of its error output."""


class ShardKilled(RuntimeError):
    """A shard's process was killed by a signal; Ray retries the shard, which resumes."""


@dataclass(frozen=True)
class ShardResult:
    """One finished shard: which, how long its last attempt took, and the command's
    closing line (e.g. ``3 item(s) made, 1 already finished (shard 1/4); …``)."""

    stage: str
    shard: int
    shards: int
    seconds: float
    summary: str


Progress = Callable[[ShardResult, int], None]
"""Called as each shard finishes, with the number of shards of its stage finished so far."""


def print_progress(result: ShardResult, finished: int) -> None:
    """The default progress report: one line per finished shard on stderr."""
    which = f" shard {result.shard}/{result.shards}" if result.shards > 1 else ""
    count = f" ({finished} of {result.shards})" if result.shards > 1 else ""
    print(
        f"tomograf.distributed: {result.stage}{which} done in {result.seconds:.1f} s{count}: "
        f"{result.summary}",
        file=sys.stderr,
        flush=True,
    )


def find_binary(binary: Optional[PathLike] = None) -> str:
    """The ``tomograf`` command line to run: ``binary``, else ``$TOMOGRAF_BIN``, else
    ``tomograf`` on ``PATH``. Raises ``FileNotFoundError`` naming what was tried."""
    if binary is None:
        binary = os.environ.get("TOMOGRAF_BIN") or shutil.which("tomograf")
    if binary is None or not Path(binary).is_file():
        raise FileNotFoundError(
            f"the tomograf command line was not found (tried: {binary or '$TOMOGRAF_BIN and PATH'}); "
            "install it (`cargo install --path .` in the repository) or pass binary=..."
        )
    return str(Path(binary).resolve())


def run_shards(
    command: Sequence[str],
    shards: int,
    *,
    stage: Optional[str] = None,
    threads: int = 1,
    binary: Optional[PathLike] = None,
    max_retries: int = 3,
    progress: Optional[Progress] = print_progress,
) -> list[ShardResult]:
    """Runs ``tomograf --threads THREADS COMMAND --shard I/SHARDS`` for every I as Ray tasks
    (each asking Ray for ``threads`` CPUs) and waits for all of them.

    Returns the shards' results in shard order. Raises ``ShardFailed`` naming every shard
    that failed, after the others have finished (their work is kept: a second call
    resumes). ``command`` is the subcommand and its arguments, without ``--shard``.
    """
    if shards < 1:
        raise ValueError(f"shards must be ≥ 1 (got {shards})")
    if threads < 1:
        raise ValueError(f"threads must be ≥ 1 (got {threads})")
    if "--shard" in command:
        raise ValueError("command must not contain --shard: run_shards adds it")
    exe = find_binary(binary)
    name = stage or command[0]
    argvs = [
        [exe, "--threads", str(threads), *map(str, command), "--shard", f"{i}/{shards}"]
        for i in range(shards)
    ]
    return _run_all(name, argvs, threads, max_retries, progress)


def run_once(
    command: Sequence[str],
    *,
    stage: Optional[str] = None,
    threads: int = 1,
    binary: Optional[PathLike] = None,
    max_retries: int = 3,
    progress: Optional[Progress] = print_progress,
) -> ShardResult:
    """Runs one unsharded ``tomograf --threads THREADS COMMAND`` as a Ray task (a merge or
    report step, on whichever node Ray picks)."""
    exe = find_binary(binary)
    argv = [exe, "--threads", str(threads), *map(str, command)]
    return _run_all(stage or command[0], [argv], threads, max_retries, progress)[0]


def dataset(output: PathLike, *args: str, shards: int, **options) -> list[ShardResult]:
    """``tomograf dataset -o OUTPUT ARGS…`` in ``shards`` shards: shard I makes the items
    ``I, I+N, …``; each rewrites ``manifest.jsonl`` after its items, and the last to finish
    lists them all. Options: those of ``run_shards`` (``threads``, ``binary``,
    ``max_retries``, ``progress``)."""
    return run_shards(["dataset", "-o", os.fspath(output), *args], shards, **options)


def evaluate(data: PathLike, output: PathLike, *args: str, shards: int, **options) -> list[ShardResult]:
    """``tomograf evaluate DATA -o OUTPUT ARGS…`` in ``shards`` shards, then ``--merge``
    (results.md and results.csv of every item). Options: those of ``run_shards``."""
    command = ["evaluate", os.fspath(data), "-o", os.fspath(output), *args]
    results = run_shards(command, shards, **options)
    merge = ["evaluate", os.fspath(data), "-o", os.fspath(output), "--merge"]
    results.append(run_once(merge, stage="evaluate merge", **options))
    return results


STUDY_STAGES = ("data", "train", "evaluate", "report")


def study(
    kind: str,
    output: PathLike,
    *args: str,
    shards: Union[int, Mapping[str, int]],
    stages: Sequence[str] = STUDY_STAGES,
    **options,
) -> list[ShardResult]:
    """``tomograf study KIND -o OUTPUT ARGS…`` stage by stage: ``data``, ``train`` and
    ``evaluate`` each in shards (a stage starts when the one before has finished on every
    shard), then ``report`` once.

    ``shards`` is one count for every stage or a count per stage (e.g. ``{"data": 16,
    "train": 4, "evaluate": 16}``: a study trains one model per level or shift, so more
    train shards than models leave some idle). Options: those of ``run_shards``.
    """
    unknown = [s for s in stages if s not in STUDY_STAGES]
    if unknown:
        raise ValueError(f"unknown study stage(s) {unknown}: choose from {list(STUDY_STAGES)}")
    results: list[ShardResult] = []
    for stage in stages:
        command = ["study", kind, "-o", os.fspath(output), *args, "--stage", stage]
        if stage == "report":
            results.append(run_once(command, stage="study report", **options))
            continue
        n = shards if isinstance(shards, int) else shards.get(stage, 1)
        results.extend(run_shards(command, n, stage=f"study {stage}", **options))
    return results


# ---------------------------------------------------------------------------------------
# The tasks.


def _run_all(
    stage: str,
    argvs: list[list[str]],
    threads: int,
    max_retries: int,
    progress: Optional[Progress],
) -> list[ShardResult]:
    import ray  # the optional dependency, needed only here

    if not ray.is_initialized():
        ray.init()
    task = ray.remote(_run_shard).options(
        num_cpus=threads,
        max_retries=max_retries,
        retry_exceptions=[ShardKilled],
    )
    shards = len(argvs)
    pending = {task.remote(stage, i, shards, argv): i for i, argv in enumerate(argvs)}
    results: dict[int, ShardResult] = {}
    failures: list[str] = []
    while pending:
        [ref], _ = ray.wait(list(pending), num_returns=1)
        i = pending.pop(ref)
        try:
            results[i] = ray.get(ref)
        except ShardFailed as e:  # Ray's task error is also an instance of the task's
            failures.append(_cause(e))
            continue
        except ray.exceptions.RayError as e:  # retries exhausted: killed every time
            failures.append(f"{stage} shard {i}/{shards}: {type(e).__name__}: {_cause(e)}")
            continue
        if progress is not None:
            progress(results[i], len(results))
    if failures:
        raise ShardFailed(
            f"{len(failures)} of {shards} {stage} shard(s) failed (the others finished; "
            "calling again resumes):\n" + "\n".join(failures)
        )
    return [results[i] for i in range(shards)]


def _cause(e: BaseException) -> str:
    """The task's own message, without Ray's traceback wrapper."""
    cause = getattr(e, "cause", None)
    return str(cause if cause is not None else e).strip()


def _run_shard(stage: str, shard: int, shards: int, argv: list[str]) -> ShardResult:
    """One attempt at one shard, inside a Ray worker."""
    start = time.monotonic()
    proc = subprocess.run(
        argv,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        errors="replace",
        preexec_fn=_die_with_parent(),
    )
    seconds = time.monotonic() - start
    err = proc.stderr.strip()
    if proc.returncode < 0:
        raise ShardKilled(
            f"{stage} shard {shard}/{shards}: killed by signal {-proc.returncode} "
            f"({signal.Signals(-proc.returncode).name}) after {seconds:.1f} s: {' '.join(argv)}"
        )
    if proc.returncode != 0:
        tail = "\n".join(err.splitlines()[-5:])
        raise ShardFailed(
            f"{stage} shard {shard}/{shards}: `{' '.join(argv)}` exited with "
            f"{proc.returncode}: {tail}"
        )
    # The command's closing line: the last one on stderr (where progress and summaries go),
    # else on stdout (e.g. `--merge` prints its table there).
    lines = [line.strip() for line in (proc.stdout + "\n" + err).splitlines() if line.strip()]
    return ShardResult(stage, shard, shards, seconds, lines[-1] if lines else "")


def _die_with_parent() -> Optional[Callable[[], None]]:
    """A ``preexec_fn`` that makes the child receive SIGKILL when the Ray worker that
    started it dies (Linux ``PR_SET_PDEATHSIG``; it survives the ``exec``), so a killed
    worker leaves no ``tomograf`` process behind to race its retry. ``None`` elsewhere."""
    if not sys.platform.startswith("linux"):
        return None
    import ctypes

    prctl = ctypes.CDLL(None, use_errno=True).prctl  # resolved before the fork
    parent = os.getpid()
    pr_set_pdeathsig = 1

    def preexec() -> None:
        prctl(pr_set_pdeathsig, int(signal.SIGKILL))
        if os.getppid() != parent:  # the worker died before prctl took effect
            os._exit(137)

    return preexec
