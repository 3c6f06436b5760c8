"""tomograf.distributed on a real local Ray cluster (2 CPUs): sharded data sets,
evaluations and a study give the one-process bytes; a Ray worker killed mid-shard is
retried and resumes; a failing shard is named, not retried, and a second call resumes.

Compared byte for byte, every file of the output trees, with two exceptions that differ
between any two one-process runs too: wall-clock ``seconds`` (a CSV column, the
per-iteration time in an evaluation's results.md, and the times of a study report's compute
table), and the output folder's own path where a
file records it (an evaluation's job.json names the PCA prior's training set)."""

import csv
import io
import os
import re
import subprocess
import textwrap
from pathlib import Path

import pytest

import ray  # bridge/requirements-test.txt: a missing Ray fails here, it is not skipped
from tomograf import distributed as td

TRAIN = ["--phantoms", "8", "--size", "16", "--views", "8"]
TEST = ["--phantoms", "4", "--seed", "100", "--size", "16", "--views", "10", "--split", "test"]


@pytest.fixture(scope="module")
def cluster():
    """A local Ray cluster of 2 CPUs, as `ray start --head --num-cpus 2` would make."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield
    ray.shutdown()


def run(cli, *args):
    """One `tomograf` process on one thread (the reference runs)."""
    subprocess.run([cli, "--threads", "1", *args], check=True, capture_output=True)


def tree(root: Path) -> dict:
    """relative path → content; see the module docstring for what is normalised."""
    out = {}
    for p in sorted(root.rglob("*")):
        if not p.is_file():
            continue
        data = p.read_bytes()
        if p.suffix in (".csv", ".md", ".html", ".json", ".jsonl", ".toml"):
            text = data.decode().replace(str(root), "<root>")
            if p.suffix == ".csv":
                text = _drop_seconds(text)
            if p.suffix in (".md", ".html"):
                text = re.sub(r"[0-9.]+ s per iteration", "<t> s per iteration", text)
                # A study report's compute table (wall-clock times of its stages).
                text = re.sub(r"[0-9]+ seconds \([0-9.]+ (?:min|h)\)", "<t>", text)
            data = text.encode()
        out[str(p.relative_to(root))] = data
    return out


def _drop_seconds(text: str) -> str:
    rows = list(csv.reader(io.StringIO(text)))
    if not rows or "seconds" not in rows[0]:
        return text
    k = rows[0].index("seconds")
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(r[:k] + r[k + 1 :] for r in rows)
    return buf.getvalue()


def assert_same_tree(a: Path, b: Path):
    ta, tb = tree(a), tree(b)
    assert sorted(ta) == sorted(tb), f"files differ: {sorted(set(ta) ^ set(tb))}"
    differ = [name for name in ta if ta[name] != tb[name]]
    assert not differ, f"contents differ: {differ}"
    assert not [n for n in ta if ".tmp" in n or "-tmp-" in n], "temporary files left"


def test_sharded_dataset_and_evaluation_match_one_process(cluster, cli_path, tmp_path):
    run(cli_path, "dataset", "-o", str(tmp_path / "one/train"), *TRAIN)
    run(cli_path, "dataset", "-o", str(tmp_path / "one/test"), *TEST)
    seen = []
    results = td.dataset(tmp_path / "ray/train", *TRAIN, shards=4, binary=cli_path,
                         progress=lambda r, n: seen.append((r.shard, n)))
    td.dataset(tmp_path / "ray/test", *TEST, shards=4, binary=cli_path, progress=None)
    assert_same_tree(tmp_path / "one/train", tmp_path / "ray/train")
    assert_same_tree(tmp_path / "one/test", tmp_path / "ray/test")
    # Progress came once per shard, counting up; every shard made its 2 items.
    assert sorted(s for s, _ in seen) == [0, 1, 2, 3]
    assert [n for _, n in seen] == [1, 2, 3, 4]
    assert all(r.summary.startswith("2 item(s) made, 0 already finished") for r in results)

    # A tiny model, then the evaluation (model, mean volume, SART-TV from the mean,
    # PCA-MAP, FDK, SART-TV from 1 and 2 views) in one process and in 4 Ray shards.
    run(cli_path, "train", str(tmp_path / "one/train"), "-o", str(tmp_path / "run"),
        "--config", "tiny", "--iterations", "20")
    args = ["--checkpoint", str(tmp_path / "run/checkpoint"), "--train-data",
            str(tmp_path / "one/train"), "--views", "1,2", "--seed", "0"]
    run(cli_path, "evaluate", str(tmp_path / "one/test"), "-o", str(tmp_path / "ev-one"), *args)
    merged = td.evaluate(tmp_path / "one/test", tmp_path / "ev-ray", *args, shards=4,
                         binary=cli_path, progress=None)
    assert_same_tree(tmp_path / "ev-one", tmp_path / "ev-ray")
    assert "TomoGRAF" in (tmp_path / "ev-ray/results.md").read_text()
    assert merged[-1].stage == "evaluate merge"


KILLER = """\
#!/bin/sh
# tomograf, except that its first run of shard 1/4 kills the Ray worker running it
# (SIGKILL, as the OOM killer would) as soon as the shard's first item is finished.
case "$*" in
  *"--shard 1/4"*)
    if mkdir "{marker}" 2>/dev/null; then
      worker=$PPID
      (while [ ! -f "{out}/00001/item.json" ]; do sleep 0.005; done; kill -9 "$worker") &
    fi ;;
esac
exec "{cli}" "$@"
"""


def test_a_killed_worker_is_retried_and_resumes_its_shard(cluster, cli_path, tmp_path):
    job = ["--phantoms", "12", "--size", "32", "--views", "8"]
    run(cli_path, "dataset", "-o", str(tmp_path / "one"), *job)
    out = tmp_path / "ray"
    wrapper = tmp_path / "tomograf-killer"
    wrapper.write_text(KILLER.format(marker=tmp_path / "killed", out=out, cli=cli_path))
    wrapper.chmod(0o755)
    results = td.dataset(out, *job, shards=4, binary=wrapper, progress=None)
    assert (tmp_path / "killed").is_dir(), "the worker was not killed"
    # Shard 1 (items 1, 5, 9) was retried after its worker died with item 1 finished: the
    # retry kept item 1 and made the rest; the other shards ran once.
    made = re.match(r"(\d+) item\(s\) made, (\d+) already finished", results[1].summary)
    assert made, results[1].summary
    assert int(made[2]) >= 1 and int(made[1]) + int(made[2]) == 3, results[1].summary
    print("the retried shard:", results[1].summary)
    for r in (results[0], results[2], results[3]):
        assert r.summary.startswith("3 item(s) made, 0 already finished"), r.summary
    # No tomograf process of the dead worker is left, and the bytes are one process's.
    left = subprocess.run(["pgrep", "-f", f"dataset -o {out}"], capture_output=True, text=True)
    assert left.stdout.strip() == "", f"orphaned tomograf process(es): {left.stdout}"
    assert_same_tree(tmp_path / "one", out)


def test_a_failing_shard_is_named_and_a_second_call_resumes(cluster, cli_path, tmp_path):
    # The wrapper fails shard 2/3 once (an error exit, as a full disk would give).
    wrapper = tmp_path / "tomograf-fails-once"
    wrapper.write_text(textwrap.dedent(f"""\
        #!/bin/sh
        case "$*" in
          *"--shard 2/3"*) if mkdir "{tmp_path / 'failed'}" 2>/dev/null; then
                             echo "error: no space left on device" >&2; exit 1; fi ;;
        esac
        exec "{cli_path}" "$@"
        """))
    wrapper.chmod(0o755)
    out = tmp_path / "ray"
    with pytest.raises(td.ShardFailed, match=r"1 of 3 dataset shard\(s\) failed(.|\n)*shard 2/3.*no space left"):
        td.dataset(out, *TRAIN, shards=3, binary=wrapper, progress=None)
    assert len(list(out.glob("*/item.json"))) == 6  # shards 0 and 1: items 0, 3, 6 and 1, 4, 7
    results = td.dataset(out, *TRAIN, shards=3, binary=wrapper, progress=None)
    assert results[2].summary.startswith("2 item(s) made, 0 already finished"), results[2].summary
    assert results[0].summary.startswith("0 item(s) made, 3 already finished"), results[0].summary
    run(cli_path, "dataset", "-o", str(tmp_path / "one"), *TRAIN)
    assert_same_tree(tmp_path / "one", out)


STUDY = ["--scale", "tiny", "--seed", "0", "--levels", "ideal-drr,noise-blur"]


@pytest.fixture(scope="module")
def study_reference(cli_path, tmp_path_factory):
    """A tiny realism-gap study (2 levels) in one process."""
    out = tmp_path_factory.mktemp("study") / "one"
    run(cli_path, "study", "realism-gap", "-o", str(out), *STUDY)
    return out


def test_sharded_study_matches_one_process(cluster, cli_path, study_reference, tmp_path):
    results = td.study("realism-gap", tmp_path / "ray", *STUDY, binary=cli_path, progress=None,
                       shards={"data": 4, "train": 2, "evaluate": 4})
    assert [r.stage for r in results].count("study train") == 2
    assert_same_tree(study_reference, tmp_path / "ray")


def test_the_slurm_array_script_gives_the_same_study(cli_path, study_reference, tmp_path):
    """scripts/slurm/study.sbatch run as SLURM would run its array tasks (the variables
    SLURM sets, one task after another; a real one-node SLURM run is in docs/scale-out.md)."""
    script = Path(__file__).resolve().parents[2] / "scripts/slurm/study.sbatch"
    out = tmp_path / "slurm"
    env = {**os.environ, "TOMOGRAF_BIN": cli_path}
    for stage, tasks in [("data", 3), ("train", 2), ("evaluate", 3), ("report", 0)]:
        for task in range(tasks) if tasks else [None]:
            array = {} if task is None else {"SLURM_ARRAY_TASK_ID": str(task), "SLURM_ARRAY_TASK_COUNT": str(tasks)}
            subprocess.run(["bash", str(script), stage, str(out), "realism-gap", *STUDY],
                           env={**env, **array}, check=True, capture_output=True)
    assert_same_tree(study_reference, out)


def test_bad_arguments_are_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="tomograf command line was not found"):
        td.find_binary(tmp_path / "no-such-binary")
    with pytest.raises(ValueError, match="shards must be"):
        td.run_shards(["dataset"], 0, binary=os.devnull)
    with pytest.raises(ValueError, match="unknown study stage"):
        td.study("realism-gap", tmp_path, shards=1, stages=["data", "plot"])
