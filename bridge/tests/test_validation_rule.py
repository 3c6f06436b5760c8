"""scripts/validation_rule.py on evaluation folders written by hand, with answers known by
construction: a challenger ahead on every pair by a constant plus small noise is chosen; one
ahead on average but inside its interval is not; the first stays when no one is resolved."""
import subprocess
import sys
from pathlib import Path

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"
HEADER = ("item,views,method,psnr_db,ssim,rmse_hu,iterations,seconds,body_psnr_db,body_ssim,"
          "body_rmse_hu")


def folder(root: Path, name: str, body: dict) -> str:
    """An evaluation folder with TomoGRAF's body PSNR `body[(item, views)]` (and a row of
    another method that the rule must ignore)."""
    (root / name / "items").mkdir(parents=True)
    items = sorted({i for i, _ in body})
    for item in items:
        rows = [HEADER]
        for (i, v), x in sorted(body.items()):
            if i == item:
                rows.append(f"{i},{v},TomoGRAF,1,0.5,100,1,1,{x},0.5,100")
                rows.append(f"{i},{v},SART-TV,1,0.5,100,1,1,{x + 50},0.5,100")
        (root / name / "items" / f"{item}.csv").write_text("\n".join(rows) + "\n")
    return str(root / name)


def run(*args):
    out = subprocess.run([sys.executable, str(SCRIPTS / "validation_rule.py"), *args],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_a_resolved_challenger_replaces_the_first_and_an_unresolved_one_does_not(tmp_path):
    keys = [(f"{i:05d}", v) for i in range(6) for v in (1, 2)]
    base = {k: 20.0 + 0.3 * n for n, k in enumerate(keys)}
    wiggle = [0.05, -0.04, 0.03, -0.02, 0.01, -0.03] * 2
    ahead = {k: base[k] + 0.5 + w for k, w in zip(keys, wiggle)}
    # +0.6 on average but ±3 from pair to pair: not resolved.
    noisy = {k: base[k] + 0.6 + (3.0 if n % 2 else -3.0) for n, k in enumerate(keys)}
    sets = ("val-x", "val-y")
    def cand(name, body):
        return f"{name}=" + ",".join(folder(tmp_path / name, s, body) for s in sets)
    text = run(cand("a", base), cand("b", ahead), cand("c", noisy))
    assert "b − a: +0.500 ±" in text and "(resolved, ahead)" in text, text
    assert "c − a: +0.600 ±" in text and "(not resolved)" in text, text
    assert text.rstrip().endswith("The rule chooses: b."), text
    # Without b, the noisy challenger's higher mean does not win.
    text = run(cand("a2", base), cand("c2", noisy))
    assert text.rstrip().endswith("The rule chooses: a2."), text
    # Another method's rows when asked for: SART-TV's are TomoGRAF's + 50 here, so its score
    # (the mean of the four cells) is the mean of `base` + 50 = 21.65 + 50.
    text = run("--method", "SART-TV", cand("a3", base), cand("b3", ahead))
    assert "| score (mean of the cells) | | 71.650 | 72.150 |" in text, text


def test_views_keeps_only_the_view_counts_asked_for(tmp_path):
    keys = [(f"{i:05d}", v) for i in range(6) for v in (1, 2)]
    base = {k: 20.0 + 0.3 * n for n, k in enumerate(keys)}
    wiggle = [0.05, -0.04, 0.03, -0.02, 0.01, -0.03]
    # Ahead from two views only; from one view the challenger is the first plus noise.
    two = {k: base[k] + (0.5 if k[1] == 2 else wiggle[int(k[0])]) for k in keys}
    sets = ("val-x", "val-y")
    def cand(name, body):
        return f"{name}=" + ",".join(folder(tmp_path / name, s, body) for s in sets)
    text = run(cand("a", base), cand("b", two))
    assert "over 24 pairs (resolved, ahead)" in text, text
    text = run("--views", "1", cand("a1", base), cand("b1", two))
    assert "b1 − a1: +0.000 ±" in text and "over 12 pairs (not resolved)" in text, text
    assert "| val-x | 2 |" not in text and "| val-x | 1 |" in text, text
    assert text.rstrip().endswith("The rule chooses: a1."), text
