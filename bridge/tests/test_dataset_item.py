"""Data-set items from Python (`tomograf.make_item`) against the command line
(`tomograf dataset`): the same source and settings must give the same files, byte for
byte, for ideal line integrals and for real detector physics with noise."""

import json

import numpy as np
import pytest

import tomograf

FILES = ["ct.nii.gz", "projections.npy", "views.json", "item.json"]


@pytest.mark.parametrize(
    "flags, kwargs",
    [
        ([], {}),
        (
            ["--preset", "kv-flat-panel-120kvp", "--noise-seed", "5"],
            {"physics": {"acquisition": {"preset": "kv-flat-panel-120kvp", "seed": 5}}},
        ),
        (
            ["--augment", "11", "--scan-range", "17"],
            {"augment_seed": 11, "scan_range_seed": 17},
        ),
    ],
    ids=["ideal-drr", "kv-flat-panel", "augment-scan-range"],
)
def test_python_and_the_cli_make_the_same_item(tmp_path, cli, flags, kwargs):
    # Phantom seeds 3 and 4 are items 0 and 1 of the CLI set; item 1's noise depends on
    # its index, so it is the one compared.
    cli("dataset", "-o", tmp_path / "set", "--phantoms", "2", "--seed", "3", "--size", "24",
        "--views", "3", *flags)
    out = tomograf.make_item(tmp_path / "item", phantom_seed=4, index=1, size=24, views=3,
                             **kwargs)
    assert (tmp_path / "item").samefile(out)
    for f in FILES:
        ours = (tmp_path / "item" / f).read_bytes()
        theirs = (tmp_path / "set" / "00001" / f).read_bytes()
        assert ours == theirs, f
    p = np.load(tmp_path / "item" / "projections.npy")
    assert p.dtype == np.float32 and p.shape == (5, 24, 24)
    assert np.all(np.isfinite(p)) and p.max() > 0
    record = json.loads((tmp_path / "item" / "item.json").read_text())
    assert record["id"] == "00001" and record["ct_dims"] == [24, 24, 24]
    if "scan_range_seed" in kwargs:
        r = record["scan_range"]
        assert 0 <= r["from"] and r["from"] + 0.5 <= r["to"] <= 1
        assert record["augmentation"] is not None


@pytest.mark.parametrize("keep_table", [False, True], ids=["body-alone", "keep-table"])
def test_a_ct_on_a_table_makes_the_cli_item(tmp_path, cli, keep_table):
    # A CT a user brings: a full-chest phantom on a couch, as a NIfTI file.
    ct = tmp_path / "ct.nii.gz"
    cli("phantom", "--profile", "full-chest", "--table", "--seed", "2", "--dims", "40,40,24",
        "--spacing", "12,12,16", "-o", ct)
    cli("dataset", ct, "-o", tmp_path / "set", "--size", "16", "--views", "2",
        *(["--keep-table"] if keep_table else []))
    tomograf.make_item(tmp_path / "item", ct=ct, size=16, views=2, keep_table=keep_table)
    for f in FILES:
        assert (tmp_path / "item" / f).read_bytes() == (tmp_path / "set" / "00000" / f).read_bytes(), f
    record = json.loads((tmp_path / "item" / "item.json").read_text())
    assert record["frame"].startswith("LPS")
    assert ("air" in record["outside_body"]) != keep_table
    assert 0 < record["body_fraction"] < 1


def test_bad_items_are_refused_by_name(tmp_path):
    with pytest.raises(ValueError, match="exactly one source"):
        tomograf.make_item(tmp_path / "a")
    with pytest.raises(ValueError, match="exactly one source"):
        tomograf.make_item(tmp_path / "a", ct=tmp_path, phantom_seed=1)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        tomograf.make_item(tmp_path / "a", ct=tmp_path / "missing.nii.gz")
    with pytest.raises(ValueError, match="size"):
        tomograf.make_item(tmp_path / "a", phantom_seed=1, size=1)
    with pytest.raises(ValueError, match="profile|full-chest"):
        tomograf.make_item(tmp_path / "a", phantom_seed=1, profile="abdomen")
    with pytest.raises(ValueError, match="preset"):
        tomograf.make_item(tmp_path / "a", phantom_seed=1, size=8, views=1,
                           physics={"acquisition": {"preset": "no-such-preset"}})
    assert not (tmp_path / "a" / "item.json").exists()


def same_item_both_ways(tmp_path, cli, flag, value, **kwargs):
    """Phantom seed 6 as item 0 of `tomograf dataset FLAG VALUE` and by `make_item(**kwargs)`:
    asserts the same bytes, returns the item's spec as recorded."""
    cli("dataset", "-o", tmp_path / "set", "--phantoms", "1", "--seed", "6", "--size", "16",
        "--views", "2", flag, value)
    tomograf.make_item(tmp_path / "item", phantom_seed=6, size=16, views=2, **kwargs)
    for f in FILES:
        assert (tmp_path / "item" / f).read_bytes() == (tmp_path / "set" / "00000" / f).read_bytes(), f
    return json.loads((tmp_path / "item" / "item.json").read_text())["source"]["spec"]


def test_organ_spread_from_python_makes_the_cli_item(tmp_path, cli):
    # A phantom whose heart and domes come from ranges 2.5 times as wide: the same bytes
    # both ways, the spread recorded in the item's source, and another volume than at 1.
    spec = same_item_both_ways(tmp_path, cli, "--organ-spread", "2.5", organ_spread=2.5)
    assert spec["organ_spread"] == 2.5
    tomograf.make_item(tmp_path / "plain", phantom_seed=6, size=16, views=2)
    plain = json.loads((tmp_path / "plain" / "item.json").read_text())
    assert "organ_spread" not in plain["source"]["spec"]
    assert (tmp_path / "plain" / "ct.nii.gz").read_bytes() != (tmp_path / "item" / "ct.nii.gz").read_bytes()
    with pytest.raises(ValueError, match="organ spread"):
        tomograf.make_item(tmp_path / "bad", phantom_seed=6, size=16, views=2, organ_spread=-1.0)


def test_deformation_from_python_makes_the_cli_item(tmp_path, cli):
    spec = same_item_both_ways(tmp_path, cli, "--deform", "5", deform_mm=5.0)
    assert spec["deform_mm"] == 5.0
    with pytest.raises(ValueError, match="deformation"):
        tomograf.make_item(tmp_path / "bad", phantom_seed=6, size=16, views=2, deform_mm=40.0)
