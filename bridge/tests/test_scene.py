"""Scenes from Python (`tomograf.render_scene`) against the command line
(`tomograf project --scene`): the same scene must give the same bytes, ideal DRR and
real detector physics with scatter alike, whether the scene is a file or a dict."""

import json

import numpy as np
import pytest

import tomograf

# A small scene: the built-in phantom on a coarse grid, two 24×32 views.
BASE = {
    "volume": {"phantom_dims": [48, 48, 24], "phantom_spacing_mm": [7.0, 7.0, 12.0]},
    "detector": {"rows": 24, "cols": 32, "pitch_mm": [12.0, 12.0]},
    "views": {"poses": ["ap", "30,10"]},
}

PHYSICS = {
    **BASE,
    "acquisition": {"preset": "kv-flat-panel-120kvp", "seed": 11},
    "scatter": {"model": "estimate", "photons": 2000},
}


def toml_of(scene):
    """TOML text of a two-level dict of scalars and lists (all these scenes use)."""

    def value(v):
        if isinstance(v, str):
            return f'"{v}"'
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    lines = []
    for table, keys in scene.items():
        lines.append(f"[{table}]")
        lines += [f"{k} = {value(v)}" for k, v in keys.items()]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("scene", [BASE, PHYSICS], ids=["ideal-drr", "kv-flat-panel-scatter"])
def test_python_and_the_cli_render_a_scene_to_the_same_bytes(tmp_path, cli, scene):
    path = tmp_path / "scene.toml"
    path.write_text(toml_of(scene))
    cli("project", "--scene", path, "-o", tmp_path / "out", "--format", "npy")
    from_cli = np.load(tmp_path / "out" / "drr.npy")
    from_file = tomograf.render_scene(path)
    from_dict = tomograf.render_scene(scene)
    assert from_file.dtype == np.float32 and from_file.shape == (2, 24, 32)
    assert np.all(np.isfinite(from_file)) and from_file.max() > 0
    assert from_file.tobytes() == from_cli.tobytes()
    assert from_dict.tobytes() == from_cli.tobytes()


def test_the_ideal_drr_of_a_scene_is_the_projector_of_its_volume():
    # The same views built with the geometry API (the scene's defaults: cone beam, SAD
    # 1000 mm, SID 1500 mm, isocentre at the volume's centre; HU → mu at 60 keV) and
    # rendered by tomograf.project, which knows nothing of scenes.
    image = tomograf.render_scene(BASE)
    hu = tomograf.thorax(dims=(48, 48, 24), spacing_mm=(7.0, 7.0, 12.0))
    geometry = tomograf.Geometry.cone(
        1000.0, 1500.0, tomograf.Detector(24, 32, 12.0), isocentre=hu.centre
    )
    views = geometry.views(["ap", "30,10"])
    direct = tomograf.project(hu.to_mu(energy_kev=60.0), views)
    assert image.shape == direct.shape == (2, 24, 32)
    np.testing.assert_array_equal(image, direct)
    assert float(image.max()) > 1.0  # a chest's line integrals reach several units


def test_bad_scenes_are_refused_by_name(tmp_path):
    with pytest.raises(ValueError, match="unknown field `colour`"):
        tomograf.render_scene({**BASE, "detector": {"colour": "red"}})
    with pytest.raises(ValueError, match="unknown preset|kv-flat-panel-120kvp"):
        tomograf.render_scene({**BASE, "acquisition": {"preset": "xray-9000"}})
    with pytest.raises(FileNotFoundError, match="nowhere.toml"):
        tomograf.render_scene(tmp_path / "nowhere.toml")
    with pytest.raises(ValueError, match="no ray of any view meets the volume"):
        tomograf.render_scene({**BASE, "geometry": {"isocentre_mm": [5000.0, 0.0, 0.0]}})


def test_project_scene_writes_the_files_the_cli_writes(tmp_path, cli):
    """`tomograf.project_scene` is `tomograf project --scene`: every file the command line
    writes (images in three formats, the .npy stack, the sidecar) comes out byte for byte
    the same; progress reports count the views; a raising callback's exception is re-raised."""
    scene = {**PHYSICS, "output": {"formats": ["npy", "tiff", "png"], "dir": str(tmp_path / "py")}}
    path = tmp_path / "scene.toml"
    path.write_text(toml_of({k: v for k, v in scene.items() if k != "output"}))
    cli("project", "--scene", path, "-o", tmp_path / "cli", "--format", "npy,tiff,png")
    reports = []
    summary = tomograf.project_scene(scene, progress=lambda *r: reports.append(r))
    assert summary["views"] == 2 and (summary["rows"], summary["cols"]) == (24, 32)
    assert summary["files"] == 2 * 2 + 1 + 1  # tiff + png per view, the stack, the sidecar
    assert reports[0] == ("view", 0, 2, "") and reports[-1] == ("view", 2, 2, "")
    names = sorted(p.name for p in (tmp_path / "cli").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "py").iterdir())
    assert "drr.json" in names and "drr_001.tiff" in names
    for name in names:
        a, b = (tmp_path / d / name for d in ("cli", "py"))
        if name.endswith(".json"):
            # The sidecars differ only where the scene came from (a file or a dict).
            ja, jb = json.loads(a.read_text()), json.loads(b.read_text())
            assert ja["views"] == jb["views"] and ja["acquisition"] == jb["acquisition"]
        else:
            assert a.read_bytes() == b.read_bytes(), name

    def stop(stage, done, total, message):
        raise KeyboardInterrupt("stop")

    with pytest.raises(KeyboardInterrupt, match="stop"):
        tomograf.project_scene({**scene, "output": {"dir": str(tmp_path / "stopped")}}, progress=stop)
