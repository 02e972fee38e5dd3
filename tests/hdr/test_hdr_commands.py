"""`scanlight expand` / `scanlight evaluate expansion` through their add_*/run functions."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from app.commands import evaluate, expand
from app.errors import ScanlightError, UsageError
from app.hdr.job import load_cameras


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    from app.demo.cache import load_demo
    from app.io.exr import write_exr
    from app.io.pointcloud import save_cloud
    d = load_demo(50_000)
    root = tmp_path_factory.mktemp("expand")
    save_cloud(d.ldr, root / "ldr.ply")
    save_cloud(d.gt, root / "gt.ply")
    write_exr(root / "photo.exr", d.photo)
    (root / "cams.json").write_text(json.dumps([{"position": list(d.capture_positions[0])}]))
    return root, d


def _parse(add, argv):
    p = argparse.ArgumentParser()
    add(p)
    return p.parse_args(argv)


def _expand_args(root, *extra):
    return _parse(expand.add_arguments,
                  ["--cloud", str(root / "ldr.ply"), "--photo", str(root / "photo.exr"),
                   "--cameras", str(root / "cams.json"), "--out", str(root / "hdr.ply"),
                   "--report", str(root / "report.json"), "--face-size", "128", *extra])


def test_expand_writes_cloud_and_report_then_evaluate_scores_it(files, capsys):
    root, d = files
    assert expand.run(_expand_args(root)) == 0
    err = capsys.readouterr().err
    assert "expand:" in err and "100%" in err                    # progress on stderr
    rep = json.loads((root / "report.json").read_text())
    assert rep["method"] == "pmatch-rgb" and rep["alpha"] == pytest.approx(d.alpha, rel=0.1)
    assert rep["counts"]["points"] == len(d.ldr) and "seconds_total" in rep["timings"]
    assert rep["output"] == str(root / "hdr.ply")
    assert not list(root.glob(".hdr.*")) and not list(root.glob(".report.*"))  # no temp files left
    from app.io.pointcloud import load_cloud
    hdr = load_cloud(root / "hdr.ply")
    assert hdr.hdr and hdr.colors.max() > 5.0                    # float colours above 1 survive

    ev = _parse(evaluate.add_expansion_arguments,
                ["--cloud", str(root / "hdr.ply"), "--gt", str(root / "gt.ply"),
                 "--ldr", str(root / "ldr.ply"), "--json", str(root / "eval.json"),
                 "--renderer", "classic", "--render-size", "40"])
    assert evaluate.run_expansion(ev) == 0
    out = capsys.readouterr().out
    assert "point RMS" in out and "relit-render error: render_rms" in out
    m = json.loads((root / "eval.json").read_text())
    assert m["correspondence"] == "same order" and m["scale"] == pytest.approx(d.alpha, rel=0.01)
    assert m["rms_overexposed"] < 0.5 * m["ldr_rms_overexposed"]
    assert m["render"]["render_rel_rms"] < 0.5 * m["render"]["ldr_render_rel_rms"]


def test_evaluate_matches_shuffled_points_by_nearest_neighbour(files, tmp_path):
    root, d = files
    from app.cloud import PointCloud
    from app.hdr.evaluate import expansion_errors
    perm = np.random.default_rng(0).permutation(len(d.gt))
    shuffled = PointCloud(d.ldr.positions[perm], d.ldr.normals[perm], d.ldr.colors[perm])
    a = expansion_errors(shuffled, d.gt, exposure=d.alpha)
    b = expansion_errors(d.ldr, d.gt, exposure=d.alpha)
    assert a["correspondence"] == "nearest neighbour" and b["correspondence"] == "same order"
    assert a["rms_all"] == pytest.approx(b["rms_all"], rel=1e-6)


def test_relit_render_error_is_zero_for_ground_truth_and_large_for_ldr(files):
    """The Table 2 render error through the real renderer: the ground truth lit by itself has no
    error; the clipped LDR scan (in ground-truth units) lights the asset visibly darker."""
    _, d = files
    from app.hdr.evaluate import render_errors
    opts = {"renderer": "classic", "size": 40, "microbuffer": 8, "scale": d.alpha}
    same = render_errors(d.gt, d.gt, None, dict(opts, scale=1.0))
    assert same["render_rms"] < 1e-6 and same["render_ssim"] > 0.999
    ldr = render_errors(d.ldr, d.gt, None, opts)
    assert ldr["render_rel_rms"] > 0.3 and ldr["render_ssim"] < same["render_ssim"]


def test_missing_and_bad_inputs_are_one_line_errors(files, tmp_path):
    root, _ = files
    args = _expand_args(root)
    args.cloud = str(tmp_path / "nope.ply")
    with pytest.raises(ScanlightError, match="nope.ply"):
        expand.run(args)
    bad = tmp_path / "cams.json"
    for text, phrase in [("{not json", "not valid JSON"), ("[]", "non-empty"),
                         ('[{"position": [1, 2]}]', "3 finite numbers")]:
        bad.write_text(text)
        args = _expand_args(root)
        args.cameras = str(bad)
        with pytest.raises(ScanlightError, match=phrase) as exc:
            expand.run(args)
        assert str(bad) in str(exc.value)
    with pytest.raises(UsageError, match="--tl"):
        expand.run(_expand_args(root, "--tl", "2"))
    with pytest.raises(UsageError, match="--params: unknown ExpandParams field 'nope'"):
        expand.run(_expand_args(root, "--params", '{"nope": 1}'))
    with pytest.raises(UsageError, match="--params: .*'pm_levels' must be in"):
        expand.run(_expand_args(root, "--params", '{"pm_levels": 99}'))
    with pytest.raises(UsageError, match="--pm-scale-min .* below --pm-scale-max"):
        expand.run(_expand_args(root, "--pm-scale-min", "8"))


def test_expand_options_come_from_the_table(files):
    """Defaults are the table's (face size 512, as in the viewer); --params fills in fields,
    a flag given with another value wins over it; --exposure is --alpha, deprecated."""
    from app.hdr.pipeline import ExpandParams
    root, _ = files
    p = _parse(expand.add_arguments, ["--cloud", "c", "--photo", "p", "--cameras", "j",
                                      "--out", "o.ply"])
    assert expand.expand_params(p) == ExpandParams()
    args = _expand_args(root, "--k", "8", "--th", "2", "--method", "landis",
                        "--params", '{"pm_iterations": 6, "hdr.neighbours": 4, "seed": 7}')
    assert expand.expand_params(args) == ExpandParams(
        face_size=128, neighbours=8, threshold_ssd=2.0, method="landis", pm_iterations=6,
        seed=7)
    assert expand.expand_params(_expand_args(root, "--exposure", "0.25")).alpha == 0.25


def test_failed_run_leaves_no_output(files, tmp_path):
    """An all-black photo is refused inside the job: the error comes back, nothing is written."""
    root, _ = files
    from app.io.exr import write_exr
    write_exr(tmp_path / "black.exr", np.zeros((32, 32, 3), np.float32))
    args = _expand_args(root)
    args.photo, args.out = str(tmp_path / "black.exr"), str(tmp_path / "out.ply")
    args.report = str(tmp_path / "rep.json")
    with pytest.raises(ScanlightError, match="all black") as exc:
        expand.run(args)
    assert "black.exr" in str(exc.value)
    assert list(tmp_path.iterdir()) == [tmp_path / "black.exr"]


def test_load_cameras_accepts_positions_and_full_cameras(tmp_path):
    p = tmp_path / "c.json"
    p.write_text(json.dumps({"cameras": [[0, 1, 2], {"position": [1, 1, 1]},
                                         {"position": [0, 1, 0], "look_at": [0, 1, -1],
                                          "width": 64, "height": 32}]}))
    cams = load_cameras(p)
    assert np.allclose(cams[0], [0, 1, 2]) and np.allclose(cams[1], [1, 1, 1])
    assert cams[2].width == 64 and cams[2].height == 32
