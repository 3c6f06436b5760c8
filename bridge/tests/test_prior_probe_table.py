"""scripts/prior_probe_table.py on evaluation folders whose answers are known by construction:
three items, TomoGRAF − SART-TV from the mean = 2, 3, 4 dB in the base set (mean 3, sd 1:
half-width t(0.975, 2) · 1/√3 = 4.303/1.732 = 2.48) and 1 dB less on every item in the variant;
the sweeps ran (TomoGRAF ≠ its network alone) on one item of the variant."""
import csv
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "prior_probe_table.py"
HEADER = ["item", "views", "method", "psnr_db", "ssim", "rmse_hu", "iterations", "seconds",
          "body_psnr_db", "body_ssim", "body_rmse_hu"]


def write(folder: Path, lead: list[float], swept: set[str]) -> Path:
    folder.mkdir(parents=True)
    with open(folder / "results.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(HEADER)
        for n, d in enumerate(lead):
            item = f"0000{n}"
            body = {"SART-TV from the mean": 20.0, "mean training volume": 18.0,
                    "TomoGRAF (network only)": 20.0 + d,
                    "TomoGRAF": 20.0 + d + (0.5 if item in swept else 0.0)}
            for method, b in body.items():
                w.writerow([item, 2, method, b, 0.5, 100, 0, 1.0, b, 0.5, 100])
    return folder


def test_the_table_pairs_items_and_variants(tmp_path):
    base = write(tmp_path / "base", [2.0, 3.0, 4.0], set())
    # The variant: 1 dB less lead on every item before the sweeps; the sweeps add 0.5 on item 1.
    variant = write(tmp_path / "deform", [1.0, 2.0, 3.0], {"00001"})
    out = subprocess.run([sys.executable, SCRIPT, f"lidc-base={base}", f"lidc-deform5={variant}"],
                         capture_output=True, text=True, check=True).stdout
    rows = {line.split("|")[1].strip(): line for line in out.splitlines() if line.startswith("| lidc")}
    assert "| 23.00 | 23.00 | 20.00 | 18.00 | 0 of 3 | +3.00 ± 2.48 (ahead) | +5.00 ± 2.48 (ahead) |" \
        in rows["lidc-base"]
    assert "1 of 3" in rows["lidc-deform5"] and "+2.17 ±" in rows["lidc-deform5"]
    # The variant against its base: −1, −0.5, −1 → mean −0.83, sd 0.289, half-width 0.72.
    assert "| lidc-deform5 against lidc-base | 2 | -0.83 ± 0.72 (behind) |" in out
