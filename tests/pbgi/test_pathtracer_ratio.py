"""``scanlight bench pathtracer-ratio`` (app/bench/pathtracer_ratio.py): the noise fit, the
reference-noise correction and the equal-error solve against a numpy model of Monte Carlo
renders with a known per-sample error; the whole bench end to end only where Mitsuba 3 is
installed (CI does not install it)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from app.bench import image_metrics as im
from app.bench import pathtracer_ratio as P

SIDE = 64
A = 2.5                 # the model's per-pixel relative RMSE at 1 spp
SWEEP = (4, 16, 64)


def _truth(rng) -> np.ndarray:
    """A smooth positive image (h, w, 3), mean luminance near 1."""
    y, x = np.mgrid[0:SIDE, 0:SIDE] / SIDE
    base = 0.6 + 0.5 * np.sin(3 * x) * np.cos(2 * y) + 0.3 * x
    return np.stack([base, 0.9 * base, 1.1 * base], -1) * (1 + 0.05 * rng.random((SIDE, SIDE, 1)))


class Model:
    """Monte Carlo renders of ``truth``: an s-spp image is truth + noise of per-pixel standard
    deviation sigma / sqrt(s), sigma scaled so that the 1-spp relative RMSE is A exactly in
    expectation (sigma varies over the image, as a path tracer's does)."""

    def __init__(self, seed=0):
        self.rng = np.random.default_rng(seed)
        self.truth = _truth(self.rng)
        shape = 0.5 + self.rng.random((SIDE, SIDE, 1))
        mean = float((self.truth.reshape(-1, 3) @ im.LUMA).mean())
        self.sigma = shape * A * mean / np.sqrt((shape ** 2).mean())

    def render(self, spp: float) -> np.ndarray:
        noise = self.rng.standard_normal(self.truth.shape)
        return self.truth + self.sigma * noise / math.sqrt(spp)

    def sweep(self, reference, spp=SWEEP) -> list[float]:
        return [im.relative_rmse(self.render(s), reference) for s in spp]


def test_the_fit_recovers_the_per_sample_error():
    m = Model(1)
    ref_spp = 16384
    fit = P.fit_noise(SWEEP, m.sweep(m.render(ref_spp)), ref_spp)
    assert fit.a == pytest.approx(A, rel=0.03)
    assert fit.slope == pytest.approx(-0.5, abs=0.03)
    assert fit.error(100) == pytest.approx(A / 10, rel=0.03)


def test_the_reference_noise_is_subtracted_in_quadrature():
    """A reference of few samples: its noise is 0.7x the error at 64 spp. The corrected fit
    still finds a; the naive fit (err = a / sqrt(spp), no floor) is biased high; our error
    against that reference loses the reference's part."""
    m = Model(2)
    ref_spp = 128
    ref = m.render(ref_spp)
    errors = m.sweep(ref)
    fit = P.fit_noise(SWEEP, errors, ref_spp)
    assert fit.a == pytest.approx(A, rel=0.03)
    naive = float(np.exp(np.mean(np.log(np.asarray(errors) * np.sqrt(SWEEP)))))
    assert naive > 1.07 * A
    assert fit.ref_noise == pytest.approx(A / math.sqrt(ref_spp), rel=0.03)
    # "ours": the truth with a known, deterministic error of about 20% of the mean
    mean = float((m.truth.reshape(-1, 3) @ im.LUMA).mean())
    ours = m.truth + 0.3 * mean * np.cos(np.arange(SIDE))[None, :, None]
    true = im.relative_rmse(ours, m.truth)
    measured = im.relative_rmse(ours, ref)
    assert measured > 1.1 * true
    assert P.true_error(measured, fit) == pytest.approx(true, rel=0.03)


def test_the_error_terms_are_the_metric_s_pixels():
    """numpy twin: the bootstrap's per-pixel terms average to image_metrics' relative RMSE^2."""
    m = Model(4)
    img, ref = m.render(16), m.render(1024)
    mask = np.zeros((SIDE, SIDE), bool)
    mask[5:50, 9:60] = True
    terms = P.error_terms(img, ref, mask)
    assert terms.shape == (mask.sum(),)
    assert math.sqrt(terms.mean()) == pytest.approx(im.relative_rmse(img, ref, mask), rel=1e-12)


def test_the_equal_error_spp_and_time():
    """Exact arithmetic on a given fit and interval."""
    fit = P.NoiseFit(a=2.0, ref_spp=4096, slope=-0.5)
    measured = math.sqrt(0.1 ** 2 + fit.ref_noise ** 2)
    eq = P.equal_error(fit, measured, 0.5, 0.01, (300.0, 500.0))
    assert eq["resolved"] == 1.0
    assert eq["error_true"] == pytest.approx(0.1, rel=1e-12)
    assert eq["spp_needed"] == pytest.approx(400.0, rel=1e-12)
    assert eq["pt_seconds"] == pytest.approx(4.0, rel=1e-12)
    assert eq["ratio"] == pytest.approx(8.0, rel=1e-12)
    assert (eq["ratio_lo"], eq["ratio_hi"]) == pytest.approx((6.0, 10.0), rel=1e-12)
    assert P.note(eq, SWEEP) == ""
    # far above the path tracer's error: its first sample already beats ours
    eq = P.equal_error(fit, 5.0, 2.0, 0.01, (0.1, 0.2))
    assert eq["resolved"] and eq["spp_needed"] < 1 and eq["pt_seconds"] == pytest.approx(0.01)
    assert "1 spp" in P.note(eq, SWEEP)


def _ours(m: Model, amplitude: float) -> np.ndarray:
    """The truth with a deterministic relative error pattern of ``amplitude``."""
    return m.truth * (1 + amplitude * np.sin(np.arange(SIDE) / 3.0))[:, None, None]


def _sweep_and_fit(m, ref_spp: int = 1024):
    """A reference of the model at ``ref_spp``, the sweep's error terms against it over the
    whole image, and the noise fit: (ref_spp, ref, mask, sweep_terms, fit)."""
    ref = m.render(ref_spp)
    mask = np.ones((SIDE, SIDE), bool)
    sweep_terms = [P.error_terms(m.render(s), ref, mask) for s in SWEEP]
    fit = P.fit_noise(SWEEP, [math.sqrt(t.mean()) for t in sweep_terms], ref_spp)
    return ref_spp, ref, mask, sweep_terms, fit


def test_the_solve_finds_the_spp_of_equal_error_beyond_the_reference():
    """The model, our true error half the reference's noise: the solved spp (about 4x the
    reference's) has our error, within the bootstrap interval, which resolves it."""
    m = Model(3)
    ref_spp, ref, mask, sweep_terms, fit = _sweep_and_fit(m)
    ours = _ours(m, 0.055)
    target = im.relative_rmse(ours, m.truth)
    assert 0.4 < target / (A / math.sqrt(ref_spp)) < 0.6
    terms = P.error_terms(ours, ref, mask)
    interval = P.spp_interval(terms, sweep_terms, SWEEP, ref_spp)
    eq = P.equal_error(fit, math.sqrt(terms.mean()), 1.0, 1.0, interval)
    assert eq["resolved"] == 1.0 and eq["spp_needed"] > 2 * ref_spp
    exact = A ** 2 / target ** 2                       # the model's spp at our error
    assert eq["spp_lo"] / 1.2 < exact < eq["spp_hi"] * 1.2
    assert eq["spp_needed"] == pytest.approx(exact, rel=0.25)
    again = np.mean([im.relative_rmse(m.render(eq["spp_needed"]), m.truth) for _ in range(4)])
    assert again == pytest.approx(target, rel=0.12)


def test_an_error_below_what_the_fit_resolves_gets_only_a_bound():
    """Our image exactly the truth: the corrected error is zero within the noise; no ratio."""
    m = Model(5)
    ref_spp, ref, mask, sweep_terms, fit = _sweep_and_fit(m)
    terms = P.error_terms(m.truth, ref, mask)
    interval = P.spp_interval(terms, sweep_terms, SWEEP, ref_spp)
    eq = P.equal_error(fit, math.sqrt(terms.mean()), 2.0, 0.01, interval)
    assert eq["resolved"] == 0.0
    assert math.isnan(eq["ratio"]) and math.isnan(eq["spp_needed"])
    assert eq["ratio_lower"] >= 0.01 * min(interval[0], ref_spp) / 2.0 > 0
    assert P.note(eq, SWEEP).startswith(P.BELOW)
    # our image the reference itself: every resample puts it below the reference's noise
    same = P.spp_interval(np.zeros_like(terms), sweep_terms, SWEEP, ref_spp)
    assert same == (math.inf, math.inf)
    # the bound's two sources, and a too-wide interval
    fit = P.NoiseFit(a=2.0, ref_spp=1024, slope=-0.5)
    eq = P.equal_error(fit, 0.05, 2.0, 0.01, (math.inf, math.inf))
    assert not eq["resolved"] and eq["ratio_lower"] == pytest.approx(1024 * 0.01 / 2.0)
    eq = P.equal_error(fit, 0.1, 2.0, 0.01, (3000.0, math.inf))
    assert not eq["resolved"] and eq["ratio_lower"] == pytest.approx(3000 * 0.01 / 2.0)
    eq = P.equal_error(fit, 0.1, 2.0, 0.01, (300.0, 900.0))
    assert not eq["resolved"] and eq["ratio_lower"] == pytest.approx(300 * 0.01 / 2.0)


def test_a_non_finite_image_gets_neither_ratio_nor_bound():
    nan = float("nan")
    eq = P.equal_error(P.NoiseFit(2.0, 1024, -0.5), float("inf"), 1.0, 0.01, (nan, nan))
    assert eq["resolved"] == 0.0 and math.isnan(eq["ratio"]) and math.isnan(eq["ratio_lower"])
    assert P.note(eq, SWEEP) == "our image is not finite"


def test_the_summary_has_a_ratio_or_a_bound_per_case_and_setting():
    fit = P.NoiseFit(a=2.0, ref_spp=1024, slope=-0.5)
    nan = float("nan")

    def rec(view, setting, eq):
        return {"case": {"room": "demo", "asset": "sphere", "material": "diffuse", "view": view,
                         "setting": setting}, "metrics": eq}
    records = [rec("closeup", "balanced", P.equal_error(fit, 0.2, 0.5, 0.01, (300.0, 500.0))),
               rec("closeup", "final", P.equal_error(fit, 0.07, 2.0, 0.01,
                                                     (math.inf, math.inf))),
               rec("whole", "balanced", P.equal_error(fit, math.inf, 1.0, 0.01, (nan, nan)))]
    lines = P.summary(records).splitlines()
    assert lines[0] == "| room | asset | view | material | balanced | final |"
    spp = 2.0 ** 2 / (0.2 ** 2 - fit.ref_noise ** 2)
    assert lines[2] == f"| demo | sphere | closeup | diffuse | {spp * 0.01 / 0.5:.3g}x | > 5.12x |"
    assert lines[3] == "| demo | sphere | whole | diffuse | - | - |"


def test_every_setting_makes_valid_render_params():
    """Each setting the bench renders makes valid render parameters (Mitsuba not needed): a
    preset key only the viewer reads (pbgi.rough_idle_passes) once made every preset fail."""
    from app.params import QUALITY_PRESETS
    from app.pbgi.renderer import RenderParams
    names = []
    for s in P.settings():
        RenderParams.from_dict(s.params).validated()
        names.append(s.name)
    assert set(QUALITY_PRESETS) <= set(names)


@pytest.mark.parametrize("flags", [["--sweep", "4"], ["--sweep", "4,x"], ["--ref-spp", "100"],
                                   ["--ref-spp", "0"], ["--viewport", "8"], ["--viewport", "0"],
                                   ["--frames", "0"],
                                   ["--settings", "nothing"], ["--rooms", "attic"]])
def test_bad_flags_are_usage_errors(flags, capsys):
    """Refused before anything is rendered: one line, exit 2."""
    from app.cli import main
    assert main(["bench", "pathtracer-ratio", *flags]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("scanlight bench: error:") and "\n" not in err


def test_the_fit_refuses_errors_it_cannot_use():
    with pytest.raises(ValueError):
        P.fit_noise((4, 16), (0.1, 0.0), 1024)
    with pytest.raises(ValueError):
        P.fit_noise((4,), (0.1,), 1024)


def test_the_quick_run_end_to_end(tmp_path, capsys):
    """The bench as the CLI runs it, on a smaller --quick (48 px, one frame, two settings):
    the path tracer's errors fall as 1/sqrt(spp), the model's reference noise matches the
    one measured from the reference's halves, and every row has a ratio or says why not."""
    pytest.importorskip("mitsuba")
    from app.cli import main
    out = tmp_path / "r.json"
    rc = main(["bench", "pathtracer-ratio", "--quick", "--viewport", "48", "--frames", "1",
               "--ref-spp", "512", "--settings", "hybrid", "--references", str(tmp_path),
               "--json", str(out)])
    assert rc in (0, None)
    text = capsys.readouterr().out
    assert "| room | asset | material | view | setting | ours ms" in text
    records = json.loads(out.read_text())
    assert [r["case"]["setting"] for r in records] == ["hybrid m=16 scale=1"]
    for r in records:
        m = r["metrics"]
        assert m["ms"] > 0 and 0 < m["rel_rmse"] < 1
        errs = [m[f"pt_err_{s}spp"] for s in SWEEP]
        assert errs[0] > errs[1] > errs[2]
        assert -0.65 < m["pt_slope"] < -0.35
        assert m["ref_noise"] == pytest.approx(m["ref_noise_halves"], rel=0.35)
        if m["resolved"]:
            assert m["ratio"] == pytest.approx(m["pt_seconds"] / (m["ms"] / 1e3), rel=1e-6)
            assert m["ratio_lo"] <= m["ratio"] <= m["ratio_hi"] <= 2 * m["ratio_lo"]
        else:
            assert m["ratio_lower"] > 0
    assert any(p.suffix == ".exr" for p in tmp_path.iterdir())     # the reference is cached
