#!/usr/bin/env python3
"""One data set of several: the items of each SRC, in order, renumbered 00000, 00001, ….

    python3 scripts/merge_sets.py DST SRC [SRC …]

Each item folder is copied and its id and index rewritten in item.json and the manifest;
DST is written as DST.partial and renamed when complete. An existing DST is kept when it was
merged from the same SRCs (DST/merged_from.json) — or, made before that record, holds as many
items as they do; otherwise the merge stops with an error naming both, rather than silently
reusing a set of other items.
Used for the mixed-population training set (scripts/prior_mix.sh, scripts/real_cts.sh).
"""
import json
import pathlib
import shutil
import sys

if len(sys.argv) < 3:
    sys.exit(__doc__)
dst = pathlib.Path(sys.argv[1])
srcs = [str(pathlib.Path(s).resolve()) for s in sys.argv[2:]]


def count(folder):
    return sum(1 for line in (folder / "manifest.jsonl").read_text().splitlines() if line.strip())


if (dst / "manifest.jsonl").exists():
    record = dst / "merged_from.json"
    if record.exists():
        if json.loads(record.read_text()) != srcs:
            sys.exit(f"{dst} exists, merged from {json.loads(record.read_text())}, not from {srcs}: "
                     "remove it or merge into another folder")
    else:
        want = sum(count(pathlib.Path(s)) for s in srcs)
        if count(dst) != want:
            sys.exit(f"{dst} exists with {count(dst)} items, but {srcs} hold {want}: "
                     "remove it or merge into another folder")
    sys.exit(0)
tmp = dst.with_name(dst.name + ".partial")
shutil.rmtree(tmp, ignore_errors=True)
tmp.mkdir(parents=True)
lines = []
for src in map(pathlib.Path, sys.argv[2:]):
    for line in (src / "manifest.jsonl").read_text().splitlines():
        if not line.strip():
            continue
        rec = json.loads(line)
        new = f"{len(lines):05d}"
        shutil.copytree(src / rec["id"], tmp / new)
        item = json.loads((tmp / new / "item.json").read_text())
        for r in (rec, item):
            r["id"], r["index"] = new, len(lines)
        (tmp / new / "item.json").write_text(json.dumps(item))
        lines.append(json.dumps(rec))
(tmp / "manifest.jsonl").write_text("\n".join(lines) + "\n")
(tmp / "merged_from.json").write_text(json.dumps(srcs))
tmp.rename(dst)
