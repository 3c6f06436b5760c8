"""scripts/merge_sets.py on data sets written by hand: items renumbered in order, and an
existing destination reused only when it was merged from the same sources — a folder of
other items (the 128-item mixed set where the 256-item one was asked for) is an error, not a
silent reuse."""
import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "merge_sets.py"


def make_set(root: Path, name: str, n: int) -> Path:
    d = root / name
    lines = []
    for i in range(n):
        item = d / f"{i:05d}"
        item.mkdir(parents=True)
        rec = {"id": f"{i:05d}", "index": i, "tag": f"{name}-{i}"}
        (item / "item.json").write_text(json.dumps(rec))
        lines.append(json.dumps(rec))
    (d / "manifest.jsonl").write_text("\n".join(lines) + "\n")
    return d


def merge(dst, *srcs):
    return subprocess.run([sys.executable, str(SCRIPT), str(dst), *map(str, srcs)],
                          capture_output=True, text=True)


def test_items_are_renumbered_in_order(tmp_path):
    a, b = make_set(tmp_path, "a", 2), make_set(tmp_path, "b", 3)
    out = merge(tmp_path / "ab", a, b)
    assert out.returncode == 0, out.stderr
    rows = [json.loads(l) for l in (tmp_path / "ab" / "manifest.jsonl").read_text().splitlines()]
    assert [r["id"] for r in rows] == ["00000", "00001", "00002", "00003", "00004"]
    assert [r["tag"] for r in rows] == ["a-0", "a-1", "b-0", "b-1", "b-2"]
    item = json.loads((tmp_path / "ab" / "00003" / "item.json").read_text())
    assert item["id"] == "00003" and item["index"] == 3 and item["tag"] == "b-1"


def test_an_existing_merge_of_other_sets_is_an_error_and_of_the_same_is_kept(tmp_path):
    a, b, c = (make_set(tmp_path, n, 2) for n in "abc")
    assert merge(tmp_path / "m", a, b).returncode == 0
    again = merge(tmp_path / "m", a, b)
    assert again.returncode == 0, again.stderr
    other = merge(tmp_path / "m", a, b, c)
    assert other.returncode != 0 and "merged from" in other.stderr, other.stderr
    # A merge made before the record was written: judged by its item count.
    (tmp_path / "m" / "merged_from.json").unlink()
    assert merge(tmp_path / "m", a, c).returncode == 0
    short = merge(tmp_path / "m", a, b, c)
    assert short.returncode != 0 and "4 items" in short.stderr and "hold 6" in short.stderr
    # Nothing half-written is left behind.
    assert not (tmp_path / "m.partial").exists()
