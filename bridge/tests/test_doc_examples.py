"""Every Python block of README.md and docs/*.md, checked against the installed module.

A block is compiled, then run in a temporary folder (where `model/` is the repository's,
so that examples may name the shipped checkpoint as from the repository root), unless it needs what CI does not have
(a Ray cluster): then it is only compiled and its skip says why. The TOML and shell blocks
are checked by the Rust test `src/doc_examples.rs`.
"""

import os
import re

import pytest

from conftest import ROOT

# Blocks that are compiled but not run, and why (matched against the block's text).
NOT_RUN = {
    'ray.init(address="auto")': "joins a running Ray cluster and writes to /shared (the same "
    "calls run on a local cluster in test_distributed.py)",
}


def python_blocks():
    docs = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    for path in docs:
        text = path.read_text()
        for m in re.finditer(r"^```python[^\n]*\n(.*?)^```", text, re.S | re.M):
            line = text[: m.start()].count("\n") + 1
            yield pytest.param(m.group(1), id=f"{path.relative_to(ROOT)}:{line}")


BLOCKS = list(python_blocks())


def test_the_documents_have_python_examples():
    assert len(BLOCKS) >= 2, BLOCKS


@pytest.mark.parametrize("code", BLOCKS)
def test_python_example_runs(code, tmp_path):
    compiled = compile(code, "<doc example>", "exec")
    for marker, why in NOT_RUN.items():
        if marker in code:
            pytest.skip(f"compiled, not run: {why}")
    # As from the repository root (the examples name the shipped checkpoint,
    # model/checkpoints/demo), but writing into a temporary folder.
    (tmp_path / "model").symlink_to(ROOT / "model")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        exec(compiled, {"__name__": "__doc_example__"})
    finally:
        os.chdir(cwd)
