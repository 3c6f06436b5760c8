#!/usr/bin/env python3
"""One data set of several: the items of each SRC, in order, renumbered 00000, 00001, ….

    python3 scripts/merge_sets.py DST SRC [SRC …]

Each item folder is copied and its id and index rewritten in item.json and the manifest;
DST is written as DST.partial and renamed when complete (an existing DST is kept).
Used for the mixed-population training set (scripts/prior_mix.sh, scripts/real_cts.sh).
"""
import json
import pathlib
import shutil
import sys

if len(sys.argv) < 3:
    sys.exit(__doc__)
dst = pathlib.Path(sys.argv[1])
if (dst / "manifest.jsonl").exists():
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
tmp.rename(dst)
