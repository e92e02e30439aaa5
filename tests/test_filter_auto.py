"""Automatic kernel choice: the training-frame error rule and the gradient rule on scenes with known scales."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.filtering import (KernelSelection, candidate_sizes, choose_kernel_by_error, choose_kernel_by_gradient,
                           choose_kernel_by_metric, kernel_size_for_height, select_kernel, smallest_within,
                           TrainingFrame)
from pgc.registry import default_registry

H, W = 72, 96


@pytest.fixture(scope="module")
def filt():
    return default_registry().first_available("filter", ["opencv", "torch", "jax"]).create()


def garment() -> tuple[np.ndarray, np.ndarray]:
    """Garment alpha (a rectangle) and smooth low-frequency shading (what a PBR model reproduces)."""
    yy, xx = np.mgrid[:H, :W]
    alpha = np.zeros((H, W), np.float32)
    alpha[6:66, 10:86] = 1.0
    shading = 0.5 + 0.3 * np.sin(xx / 30.0)[..., None] * np.array([1.0, 0.9, 0.8])
    return alpha, shading.astype(np.float32)


def detail(period: float) -> np.ndarray:
    """Fine fabric detail of the given period (px), zero-mean: what only the Gaussians reproduce."""
    yy, xx = np.mgrid[:H, :W]
    return (0.15 * np.sin(2 * np.pi * xx / period) * np.sin(2 * np.pi * yy / period))[..., None].astype(np.float32)


def test_candidate_sizes_are_odd_sorted_and_include_the_paper_size():
    sizes = candidate_sizes(2668, 4096)
    assert sizes == sorted(set(sizes)) and all(s % 2 == 1 for s in sizes)
    assert sizes[0] == 3 and kernel_size_for_height(2668) in sizes and sizes[-1] <= 2668 // 2 + 1


def test_error_rule_scores_are_the_training_reconstruction_error(filt):
    alpha, shading = garment()
    image = shading + detail(6)
    pbr = shading * 1.05
    choice = choose_kernel_by_error(filt, TrainingFrame(image, image, alpha, pbr, alpha), sizes=[9], tolerance=0.0)
    hybrid = image - filt.lowpass(image, alpha, 9) + filt.lowpass(pbr, alpha, 9)
    assert choice.size == 9 and np.isclose(choice.scores[9], np.abs(image - hybrid)[alpha > 0].mean(), rtol=1e-5)


def test_error_rule_follows_the_scale_of_the_detail_the_pbr_model_misses(filt):
    """I = shading + detail; G (3DGS) = I with a small error; S (PBR) = shading slightly off. The error falls
    until the kernel removes the detail, then stays at the PBR's low-frequency error: the knee grows with the
    detail's period, and tolerance 0 is the arg-min."""
    alpha, shading = garment()
    rng = np.random.default_rng(0)
    chosen = []
    for period in (3, 6, 12):
        image = shading + detail(period)
        gaussians = image + 0.002 * rng.standard_normal(image.shape).astype(np.float32)
        choice = choose_kernel_by_error(filt, TrainingFrame(image, gaussians, alpha, shading * 1.05, alpha))
        assert choice.criterion == "error" and choice.size in choice.scores
        argmin = choose_kernel_by_error(filt, TrainingFrame(image, gaussians, alpha, shading * 1.05, alpha),
                                        tolerance=0.0)
        assert argmin.scores[argmin.size] == min(argmin.scores.values())
        assert period <= choice.size <= 3 * period
        chosen.append(choice.size)
    assert chosen == sorted(chosen) and chosen[0] < chosen[-1]


def test_error_rule_with_a_perfect_pbr_render_picks_the_smallest_kernel(filt):
    alpha, shading = garment()
    image = shading + detail(5)
    choice = choose_kernel_by_error(filt, TrainingFrame(image, image, alpha, image, alpha), sizes=[3, 7, 15])
    assert choice.size == 3 and max(choice.scores.values()) < 1e-6


def test_gradient_rule_blurs_until_the_detail_is_gone(filt):
    alpha, shading = garment()
    chosen = []
    for period in (3, 6, 12):
        image = shading + detail(period)
        choice = choose_kernel_by_gradient(filt, TrainingFrame(image, image, alpha), gradient_ratio=0.15)
        ratios = list(choice.scores.values())
        assert ratios[-1] <= 0.15 < min(ratios[:-1], default=1.0)  # stopped at the first size under the threshold
        assert ratios == sorted(ratios, reverse=True)
        assert period <= choice.size <= 3 * period
        chosen.append(choice.size)
    assert chosen == sorted(chosen) and chosen[0] < chosen[-1]


def test_gradient_rule_on_a_flat_garment_picks_the_smallest_kernel(filt):
    alpha, _ = garment()
    flat = np.full((H, W, 3), 0.4, np.float32)
    choice = choose_kernel_by_gradient(filt, TrainingFrame(flat, flat, alpha))
    assert choice.size == 3


def test_select_kernel_modes(filt):
    alpha, shading = garment()
    image = shading + detail(6)
    assert select_kernel(KernelSelection(), filt, TrainingFrame(image, image, alpha)).size == kernel_size_for_height(H)
    assert select_kernel(KernelSelection(mode="fixed", size=21), filt, TrainingFrame(image, image, alpha)).size == 21
    grad = select_kernel(KernelSelection(mode="gradient"), filt, TrainingFrame(image, image, alpha))
    assert grad == choose_kernel_by_gradient(filt, TrainingFrame(image, image, alpha))
    err = select_kernel(KernelSelection(mode="error", sizes=[3, 9]), filt, TrainingFrame(image, image, alpha, shading, alpha))
    assert err.criterion == "error" and set(err.scores) == {3, 9}


def test_kernel_choice_errors_are_clear(filt):
    alpha, shading = garment()
    with pytest.raises(PGCDataError, match="needs 'size'"):
        select_kernel(KernelSelection(mode="fixed"), filt, TrainingFrame(shading, shading, alpha))
    with pytest.raises(PGCDataError, match="far-field render"):
        select_kernel(KernelSelection(mode="error"), filt, TrainingFrame(shading, shading, alpha))
    with pytest.raises(PGCDataError, match="mask is empty"):
        choose_kernel_by_error(filt, TrainingFrame(shading, shading, np.zeros_like(alpha), shading, alpha))
    with pytest.raises(PGCDataError, match="same shape"):
        choose_kernel_by_error(filt, TrainingFrame(shading, shading[:10], alpha, shading, alpha))
    with pytest.raises(PGCDataError, match="kernel_size"):
        choose_kernel_by_gradient(filt, TrainingFrame(shading, shading, alpha), sizes=[4])


def _psnr():
    return default_registry().create("metric", "psnr")


def test_metric_rule_scores_are_the_metric_of_the_hybrid_on_the_garment(filt):
    alpha, shading = garment()
    image = shading + detail(6)
    pbr = shading * 1.05
    frame = TrainingFrame(image, image, alpha, pbr, alpha)
    choice = choose_kernel_by_metric(filt, [frame, frame], _psnr(), "psnr", sizes=[5, 9])
    hybrid = np.clip(image - filt.lowpass(image, alpha, 9) + filt.lowpass(pbr, alpha, 9), 0, 1) * alpha[..., None]
    expected = _psnr()(hybrid, np.clip(image, 0, 1) * alpha[..., None], alpha)
    assert choice.criterion == "metric:psnr" and np.isclose(choice.scores[9], expected, rtol=1e-6)


def test_the_kernel_rules_score_the_residual_hybrid_as_the_multiplicative_one_at_the_capture_light(filt):
    """The rules score training frames, under the capture light, where detail 'residual' is 'multiplicative'."""
    from pgc.filtering.auto import hybrid_image

    alpha, shading = garment()
    image = shading + detail(6)
    frame = TrainingFrame(image, image + 0.01, alpha, shading * 1.05 + 0.5 * detail(4), alpha)
    for size in (3, 9, 21):
        np.testing.assert_allclose(hybrid_image(filt, frame, size, "residual"),
                                   hybrid_image(filt, frame, size, "multiplicative"), atol=1e-6)


def test_metric_rule_keeps_detail_the_far_field_lacks_and_drops_noise_it_does_not(filt):
    """I = shading + detail. A far field without the detail and an exact near field: every larger kernel
    hands more of the detail to the near field, so the largest size scores best. An exact far field and a
    near field with pixel noise: every larger kernel lets more noise through, so the smallest scores best.
    Both with PSNR (higher is better) and with LPIPS (lower is better)."""
    alpha, shading = garment()
    image = shading + detail(6)
    noisy = image + 0.05 * np.random.default_rng(1).standard_normal(image.shape).astype(np.float32)
    sizes = [3, 7, 15, 31]
    lacking = TrainingFrame(image, image, alpha, shading, alpha)
    noise = TrainingFrame(image, noisy, alpha, image, alpha)
    assert choose_kernel_by_metric(filt, [lacking], _psnr(), "psnr", sizes).size == 31
    assert choose_kernel_by_metric(filt, [noise], _psnr(), "psnr", sizes).size == 3
    lpips = default_registry().create("metric", "lpips")
    assert not lpips.higher_is_better
    assert choose_kernel_by_metric(filt, [lacking], lpips, "lpips", sizes).size > 3
    assert choose_kernel_by_metric(filt, [noise], lpips, "lpips", sizes).size < 31


def test_metric_rule_ties_go_to_the_smaller_size_and_bad_frames_fail_clearly(filt):
    alpha, shading = garment()
    same = TrainingFrame(shading, shading, alpha, shading, alpha)  # every size gives the same hybrid
    assert choose_kernel_by_metric(filt, [same], _psnr(), "psnr", [3, 9, 15]).size == 3
    with pytest.raises(PGCDataError, match="far-field render"):
        choose_kernel_by_metric(filt, [TrainingFrame(shading, shading, alpha)], _psnr(), "psnr", [3])
    with pytest.raises(PGCDataError, match="at least one view"):
        choose_kernel_by_metric(filt, [], _psnr(), "psnr", [3])
    with pytest.raises(PGCDataError, match="choose_kernel_by_metric"):
        select_kernel(KernelSelection(mode="metric"), filt, same)


def test_smallest_within_takes_the_smallest_size_near_the_best_score():
    """Scores 10, 4, 1.2, 1.0 (lower is better): the range is 9; tolerance 0.1 allows 1.9, so 9 px; 0 is the
    arg-min; 1 allows every size. Higher-is-better scores mirror it."""
    loss = {3: 10.0, 5: 4.0, 9: 1.2, 15: 1.0}
    assert smallest_within(loss, 0.1) == 9
    assert smallest_within(loss, 0.0) == 15
    assert smallest_within(loss, 1.0) == 3
    assert smallest_within(loss, 0.02) == 15  # 1.2 > 1.0 + 0.18
    gain = {k: -v for k, v in loss.items()}
    assert smallest_within(gain, 0.1, higher_is_better=True) == 9
    assert smallest_within({3: 2.0, 5: 2.0}, 0.0) == 3  # a tie goes to the smaller size
    assert smallest_within({3: 20.0, 5: np.inf, 9: np.inf}, 0.5, higher_is_better=True) == 5


def test_metric_rule_tolerance_gives_up_the_last_share_of_the_score(filt):
    """The far field lacks the detail: PSNR rises with every larger kernel. With a tolerance of the whole
    range the smallest size is taken; with 0 the best; in between, the smallest size the rule's formula
    allows from the scores themselves."""
    alpha, shading = garment()
    image = shading + detail(6)
    lacking = TrainingFrame(image, image, alpha, shading, alpha)
    sizes = [3, 7, 15, 31]
    best = choose_kernel_by_metric(filt, [lacking], _psnr(), "psnr", sizes, tolerance=0.0)
    assert best.size == 31
    assert choose_kernel_by_metric(filt, [lacking], _psnr(), "psnr", sizes, tolerance=1.0).size == 3
    some = choose_kernel_by_metric(filt, [lacking], _psnr(), "psnr", sizes, tolerance=0.3)
    top, bottom = max(best.scores.values()), min(best.scores.values())
    allowed = [k for k in sizes if best.scores[k] >= top - 0.3 * (top - bottom)]
    assert some.size == min(allowed) and some.scores == best.scores


def test_metric_rule_names_a_metric_of_the_run():
    from pgc.config import resolve
    from pgc.errors import PGCConfigError

    with pytest.raises(PGCConfigError, match=r"\[stages.render.kernel\] metric = 'nope'.*add it to \[metric\] use"):
        resolve({"stages": {"render": {"kernel": {"mode": "metric", "metric": "nope"}}}})
    with pytest.raises(PGCConfigError, match=r"metric = 'lpips' is not among the run's metrics \['psnr'\]"):
        resolve({"metric": {"use": ["psnr"]}, "stages": {"render": {"kernel": {"mode": "metric"}}}})
    cfg = resolve({"stages": {"render": {"kernel": {"mode": "metric"}}}})
    assert cfg.roles["metric"].create(cfg.stage("render").kernel.metric).higher_is_better is False
    # as the default (not asked for), a run without the metric falls back to the error rule
    assert resolve().stage("render").kernel.mode == "metric"
    assert resolve({"metric": {"use": ["psnr"]}}).stage("render").kernel.mode == "error"
