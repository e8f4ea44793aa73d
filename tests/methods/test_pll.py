"""Phase-locked-loop bank (paper §3.4, §4.4, Table 6): lock, acquisition, design rule, input filters."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.signal

from methods import pll
from methods.pll.design import (
    LoopParameters,
    band_edges,
    default_filter_bandwidth,
    default_loop_bandwidth,
    input_filter_sos,
    loop_time_constants,
    omega_l_from_time_constants,
    open_loop_response,
    rule_parameters,
    stability_margins,
)

DT = 0.02
TRUE = [3.23, 20.24, 22.00, 56.67]                 # Table 6 "True frequency"
PRIOR = [2.80, 16.00, 18.00, 52.00]                # Table 6 "A priori frequency"
TABLE6 = pll.Options(                              # Table 6 and §4.4 (configs/method/pll.yaml)
    loop_bandwidth_rad_s=[0.6, 4.0, 4.0, 11.3], t_vco_s=[0.8, 0.12, 0.12, 0.045],
    t1_s=[5.7, 0.15, 0.15, 0.02], t2_s=[3.7, 0.6, 0.6, 0.22], t3_s=[0.64, 0.10, 0.10, 0.04],
    gain=[1.0, 1.0, 1.0, 1.0], filter_bandwidth_rad_s=[5.0, 9.0, 9.0, 12.0])
TABLE6_OPTIONS = {k: getattr(TABLE6, k) for k in pll.PER_LOOP_OPTIONS}
AMPLITUDE = [1.06, 3.90, 5.12, 6.47]               # docs/physics.md §3, coupled model, m/s²


def one_loop(j: int, **extra) -> dict:
    """Options of loop j of Table 6 alone."""
    return {**{k: [getattr(TABLE6, k)[j]] for k in pll.PER_LOOP_OPTIONS}, **extra}


def acquisition_time(j: int) -> float:
    return 4 * math.pi / TABLE6.loop_bandwidth_rad_s[j]                     # §3.4


def tip_like(n: int, rng=None, noise_m_s2: float = 0.0) -> np.ndarray:
    """Sum of four damped sinusoids (ζ = 0.005) with the tip-accelerometer amplitudes."""
    t = np.arange(n) * DT
    y = sum(a * np.exp(-0.005 * w * t) * np.cos(w * t) for a, w in zip(AMPLITUDE, TRUE, strict=True))
    if noise_m_s2:
        y = y + noise_m_s2 * rng.standard_normal(n)
    return y


# --- lock and acquisition -----------------------------------------------------------------------------

@pytest.mark.parametrize("input_filter", [False, True])
@pytest.mark.parametrize("j", range(4))
def test_clean_sinusoid_locks_within_twice_the_acquisition_time(j, input_filter):
    """Fig. 4 set-up: a loop alone on sin(ω t) at its true frequency, record = 2 × 4π/ω_L."""
    n = int(round(2 * acquisition_time(j) / DT))
    t = np.arange(n) * DT
    est = pll.identify(np.sin(TRUE[j] * t), DT, [PRIOR[j]], **one_loop(j, input_filter=input_filter))
    assert est.converged, est.message
    assert abs(est.frequencies[0] - TRUE[j]) < 0.005 * TRUE[j]
    assert est.history.shape == (n, 1)


@pytest.mark.parametrize("j", [0, 1, 3])
@pytest.mark.parametrize("offset", [-1.0, 1.0])
def test_pull_in_from_one_loop_bandwidth_away_for_every_start_phase(j, offset):
    """Inside the acquisition range (§3.4 says ≈ 1.5 ω_L): ω = ω₀ ± ω_L locks from any initial phase."""
    w = PRIOR[j] + offset * TABLE6.loop_bandwidth_rad_s[j]
    n = int(round(4 * acquisition_time(j) / DT))
    t = np.arange(n) * DT
    for phase in np.arange(4) * math.pi / 2:
        est = pll.identify(np.sin(w * t + phase), DT, [PRIOR[j]], **one_loop(j, input_filter=False))
        assert est.converged, (phase, est.message)
        assert abs(est.frequencies[0] - w) < 0.005 * w


@pytest.mark.parametrize("j", [1, 3])
def test_input_far_outside_the_acquisition_range_is_reported_unlocked(j):
    """3 ω_L away the loop cannot acquire: an honest 'not converged', never an exception."""
    w = PRIOR[j] + 3 * TABLE6.loop_bandwidth_rad_s[j]
    n = int(round(6 * acquisition_time(j) / DT))
    est = pll.identify(np.sin(w * np.arange(n) * DT), DT, [PRIOR[j]], **one_loop(j, input_filter=False))
    assert not est.converged
    assert "not locked" in est.message
    assert est.extra["locked"] == [False]


def test_detector_normalisation_makes_the_loop_independent_of_the_input_amplitude():
    """The AGC gives the phase detector unit gain whatever the amplitude (modes differ six-fold)."""
    t = np.arange(1000) * DT
    a = pll.identify(1e-3 * np.sin(TRUE[1] * t), DT, [PRIOR[1]], **one_loop(1))
    b = pll.identify(1e3 * np.sin(TRUE[1] * t), DT, [PRIOR[1]], **one_loop(1))
    np.testing.assert_allclose(a.history, b.history, rtol=1e-9)
    np.testing.assert_allclose(b.extra["amplitude_m_s2"], 1e3, rtol=0.05)


def test_without_normalisation_a_small_input_slows_acquisition():
    """Raw multiplier (gain A/2): at A = 0.2 the loop gain is 0.1; no acquisition within 2 × 4π/ω_L."""
    n = int(round(2 * acquisition_time(1) / DT))
    y = 0.2 * np.sin(TRUE[1] * np.arange(n) * DT)
    raw = pll.identify(y, DT, [PRIOR[1]], **one_loop(1, normalisation="none", input_filter=False))
    agc = pll.identify(y, DT, [PRIOR[1]], **one_loop(1, normalisation="agc", input_filter=False))
    assert agc.converged
    assert abs(raw.frequencies[0] - TRUE[1]) > 10 * abs(agc.frequencies[0] - TRUE[1])


def test_bank_on_a_tip_like_signal_locks_the_well_separated_modes():
    """Four damped modes, 41 s, input filters: modes 1 and 4 locked within 0.5 %; 2 and 3 interfere."""
    est = pll.identify(tip_like(2048), DT, PRIOR, output_window_s=10.0, **TABLE6_OPTIONS)
    assert est.history.shape == (2048, 4)
    assert est.extra["locked"][0]
    for j in (0, 3):
        assert abs(est.frequencies[j] - TRUE[j]) < 0.005 * TRUE[j]
    assert not est.converged                   # the 1.76 rad/s beat of modes 2 and 3 breaks their lock


# --- records the loops cannot lock on ------------------------------------------------------------------

@pytest.mark.parametrize("n", [20, 32, 64, 128, 256])
def test_short_records_are_reported_not_converged_without_exception(n):
    """0.4–5 s: shorter than (or barely as long as) the acquisition times 21, 3.1, 3.1, 1.1 s."""
    est = pll.identify(tip_like(n, np.random.default_rng(1), 1e-2), DT, PRIOR, **TABLE6_OPTIONS)
    assert not est.converged
    assert est.history.shape == (n, 4)
    assert np.all(np.isfinite(est.frequencies))
    assert not est.extra["locked"][0]
    assert "loop 1 (2.8 rad/s) not locked" in est.message


def test_pure_noise_is_not_reported_as_locked():
    est = pll.identify(np.random.default_rng(2).standard_normal(2048), DT, PRIOR, **TABLE6_OPTIONS)
    assert not est.converged
    assert not any(est.extra["locked"])


def test_identically_zero_record_fails_cleanly():
    est = pll.identify(np.zeros(100), DT, PRIOR)
    assert not est.converged
    assert np.all(np.isnan(est.frequencies))


def test_huge_noise_does_not_raise():
    est = pll.identify(tip_like(512, np.random.default_rng(3), 1e3), DT, PRIOR, **TABLE6_OPTIONS)
    assert est.history.shape == (512, 4)
    assert np.all((est.history > 0) & (est.history < math.pi / DT))


def test_invalid_options_raise_value_error():
    with pytest.raises(ValueError, match="unknown option"):
        pll.identify(np.ones(100), DT, PRIOR, bandwidth=3.0)
    with pytest.raises(ValueError, match="gain has 3 entries"):
        pll.identify(np.ones(100), DT, PRIOR, gain=[1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="design"):
        pll.identify(np.ones(100), DT, PRIOR, design="magic")
    with pytest.raises(ValueError, match=r"^filter_order = 0: "):     # the option's name, not the helper's
        pll.check_options(np.array(PRIOR), DT, filter_order=0)


# --- the design rule under eq. (37) ---------------------------------------------------------------------

def test_design_rule_gives_crossover_at_omega_l_with_the_requested_phase_margin():
    """Without T_VCO the rule puts |L(jω_L)| = K and the phase at ω_L at −180° + φ."""
    for wl, phi in [(0.6, 45.0), (4.0, 45.0), (11.3, 30.0)]:
        t1, t2, t3 = loop_time_constants(wl, phi)
        ell = open_loop_response(LoopParameters(wl, 0.0, t1, t2, t3, 1.0), np.array([wl]))[0]
        assert abs(abs(ell) - 1.0) < 1e-12
        assert abs(math.degrees(np.angle(ell)) - (-180 + phi)) < 1e-9


def test_design_rule_reproduces_table6_time_constants_for_modes_2_to_4():
    """Table 6 prints the rule's values (45°) rounded to 1–2 digits for ω_L = 4.0 and 11.3 rad/s."""
    for j, rel in [(1, 0.04), (2, 0.04), (3, 0.10)]:
        rule = loop_time_constants(TABLE6.loop_bandwidth_rad_s[j], 45.0)
        table = (TABLE6.t1_s[j], TABLE6.t2_s[j], TABLE6.t3_s[j])
        np.testing.assert_allclose(table, rule, rtol=rel)
    np.testing.assert_allclose(loop_time_constants(4.0), [0.150888, 0.603553, 0.103553], rtol=1e-5)


def test_table6_mode1_follows_the_rule_for_omega_l_0_65_not_the_printed_0_6():
    """Mode 1's T1, T2, T3 (5.7, 3.7, 0.64 s) imply ω_L ≈ 0.65 rad/s; the rule at 0.6 gives 6.7, 4.0, 0.69."""
    implied = omega_l_from_time_constants(TABLE6.t1_s[0], TABLE6.t2_s[0], TABLE6.t3_s[0])
    np.testing.assert_allclose(list(implied.values()), 0.65, rtol=0.005)
    rule_06 = loop_time_constants(0.6)
    assert rule_06[0] / TABLE6.t1_s[0] > 1.15                      # T1 departs by 18 %
    np.testing.assert_allclose(loop_time_constants(0.65), [5.7, 3.7, 0.64], rtol=0.01)


def test_rule_design_option_builds_a_working_loop_from_omega_l_alone():
    """A new mode: only ω_L given; T1–T3 by the rule, T_VCO = 0.5/ω_L."""
    w = 35.0
    t = np.arange(int(round(2 * 4 * math.pi / 8.0 / DT))) * DT
    est = pll.identify(np.sin(w * t), DT, [31.0], design="rule", loop_bandwidth_rad_s=[8.0],
                       gain=[1.0], filter_bandwidth_rad_s=[10.0])
    assert est.converged, est.message
    assert abs(est.frequencies[0] - w) < 0.005 * w


def test_table6_loops_have_about_20_degrees_of_margin_and_k5_is_unstable():
    """T_VCO (ω_L T_VCO ≈ 0.5) eats ~26° of the rule's 45°; K = 5 on mode 1 makes the loop unstable."""
    loop1 = LoopParameters(0.6, 0.8, 5.7, 3.7, 0.64, 1.0)
    m1 = stability_margins(loop1)
    assert 15 < m1["phase_margin_deg"] < 25
    assert m1["gain_margin_db"] > 6
    k5 = stability_margins(LoopParameters(0.6, 0.8, 5.7, 3.7, 0.64, 5.0), DT)
    assert k5["phase_margin_deg"] < 0 and k5["gain_margin_db"] < 0
    n = int(round(2 * acquisition_time(0) / DT))
    est = pll.identify(np.sin(TRUE[0] * np.arange(n) * DT), DT, [PRIOR[0]],
                       **one_loop(0, gain=[5.0], input_filter=False))
    assert not est.converged


# --- the Chebyshev input filters (§4.4) ----------------------------------------------------------------

@pytest.mark.parametrize("j", range(4))
def test_discretised_chebyshev_filter_has_the_specified_centre_and_band_edges(j):
    centre, bandwidth = PRIOR[j], TABLE6.filter_bandwidth_rad_s[j]
    ripple = TABLE6.filter_ripple_db
    sos = input_filter_sos(centre, bandwidth, DT, order=3, ripple_db=ripple)
    assert sos.shape == (3, 6)                                      # prototype order 3: six poles
    w1, w2 = band_edges(centre, bandwidth, DT)
    assert abs((w2 - w1) - bandwidth) < 1e-9
    _, h = scipy.signal.sosfreqz(sos, worN=np.array([w1, centre, w2]) * DT)
    gain_db = 20 * np.log10(np.abs(h))
    assert abs(gain_db[1]) < 1e-6                                   # 0 dB at the centre (odd order)
    assert abs(np.angle(h[1])) < 1e-6                               # and zero phase there
    np.testing.assert_allclose(gain_db[[0, 2]], -ripple, atol=1e-6)  # edges at −ripple dB
    inside = np.linspace(w1, w2, 200)
    _, hin = scipy.signal.sosfreqz(sos, worN=inside * DT)
    assert np.all(20 * np.log10(np.abs(hin)) > -ripple - 1e-6)     # equiripple pass band
    above = w2 + bandwidth                                          # one bandwidth above the band,
    outside = np.array([centre**2 / above, above])                  # and its geometric mirror below
    _, hout = scipy.signal.sosfreqz(sos, worN=outside * DT)
    assert np.all(20 * np.log10(np.abs(hout)) < -20)


def test_mode4_filter_rejects_the_mode2_and_mode3_frequencies():
    sos = input_filter_sos(52.0, 12.0, DT)
    _, h = scipy.signal.sosfreqz(sos, worN=np.array([20.24, 22.0]) * DT)
    assert np.all(20 * np.log10(np.abs(h)) < -50)


def test_a_loop_still_ringing_at_the_end_of_a_short_record_is_not_reported_locked():
    """1.28 s of data: loop 4 (acquisition time 1.1 s) has a high lock indicator but still swings."""
    est = pll.identify(tip_like(64), DT, PRIOR, **TABLE6_OPTIONS)
    assert np.ptp(est.history[-16:, 3]) > 0.05 * TRUE[3]           # the final quarter is a transient
    assert est.extra["lock_indicator"][3] > 0.8
    assert not est.extra["locked"][3]
    assert "drifts" in est.message


def test_agc_range_limit_makes_a_decayed_mode_hold_its_frequency():
    """Mode 4 alone, ζ = 0.005 (1/e in 3.5 s), 1000 µg, 41 s: by the final quarter the mode is below the
    noise. A pure AGC normalises the noise and wanders; limited to 20 dB the loop (roughly) holds."""
    rng = np.random.default_rng(3)
    t = np.arange(2048) * DT
    clean = 6.47 * np.exp(-0.005 * TRUE[3] * t) * np.cos(TRUE[3] * t)
    y = clean + 1000 * 9.80665e-6 * rng.standard_normal(t.size)
    free = pll.identify(y, DT, [PRIOR[3]], **one_loop(3))
    held = pll.identify(y, DT, [PRIOR[3]], **one_loop(3, agc_range_db=20.0))
    assert abs(held.frequencies[0] - TRUE[3]) < 0.02 * TRUE[3]
    assert abs(free.frequencies[0] - TRUE[3]) > 3 * abs(held.frequencies[0] - TRUE[3])
    assert held.std[0] < free.std[0]


# --- defaults derived from the prior: any number of modes, frequencies, damping, Δt -----------------------

def modes(w, a, zeta, dt, n, rng, noise_m_s2=0.0, bias_m_s2=0.0) -> np.ndarray:
    """Sum of damped sinusoids a exp(−ζωt) cos(ω√(1−ζ²) t + φ), random phases, plus bias and white noise."""
    t = np.arange(n) * dt
    phase = rng.uniform(0, 2 * math.pi, len(w))
    y = sum(ai * np.exp(-zeta * wi * t) * np.cos(wi * math.sqrt(1 - zeta**2) * t + p)
            for ai, wi, p in zip(a, w, phase, strict=True))
    return y + bias_m_s2 + noise_m_s2 * rng.standard_normal(n)


@pytest.mark.parametrize("zeta", [0.0, 0.01])
@pytest.mark.parametrize("m", [1, 2, 3, 5])
def test_default_options_accept_any_number_of_priors(m, zeta):
    """No per-loop option given: 1, 2, 3 or 5 loops are set up from the prior alone; shapes follow m."""
    w = np.array([3.0, 9.0, 25.0, 50.0, 100.0])[:m]
    dt, n = 0.01, 1500
    est = pll.identify(modes(w, np.ones(m), zeta, dt, n, np.random.default_rng(m), 1e-2), dt, 1.1 * w)
    assert est.frequencies.shape == est.std.shape == (m,)
    assert est.history.shape == est.extra["lock_history"].shape == (n, m)
    assert len(est.extra["locked"]) == len(est.converged_per_mode) == m
    for key in ("loop_bandwidth_rad_s", "filter_bandwidth_rad_s", "acquisition_time_s", "lock_indicator"):
        assert np.shape(est.extra[key]) == (m,)
    assert np.all(np.isfinite(est.frequencies))
    assert np.all((est.history > 0) & (est.history < math.pi / dt))


def test_a_three_entry_prior_with_default_options_runs_through_the_registry():
    """The call that used to raise "loop_bandwidth_rad_s has 4 entries; the prior has 3"."""
    import methods
    est = methods.get("pll")(tip_like(512), DT, [4.3, 13.5, 26.0])
    assert est.frequencies.shape == (3,) and est.history.shape == (512, 3)


def test_an_explicit_list_of_the_wrong_length_still_raises():
    with pytest.raises(ValueError, match="loop_bandwidth_rad_s has 4 entries; the prior has 3"):
        pll.identify(tip_like(512), DT, [4.3, 13.5, 26.0], **TABLE6_OPTIONS)
    with pytest.raises(ValueError, match="filter_bandwidth_rad_s has 2 entries; the prior has 3"):
        pll.identify(tip_like(512), DT, [4.3, 13.5, 26.0], filter_bandwidth_rad_s=[5.0, 9.0])


@pytest.mark.parametrize("prior", [6.3, 7.7])
def test_default_options_lock_a_clean_sinusoid_from_a_10_percent_prior_error(prior):
    """7 rad/s, prior 10 % off (ω_L = 0.22 ω₀ → pull-in ≈ ±33 %), 40 s ≈ 4–5 acquisition times."""
    n = 2000
    est = pll.identify(np.sin(7.0 * np.arange(n) * DT + 0.3), DT, [prior])
    assert n * DT > 4 * est.extra["acquisition_time_s"][0]
    assert est.converged, est.message
    assert abs(est.frequencies[0] - 7.0) < 0.005 * 7.0              # measured: ≤ 0.012 %


@pytest.mark.parametrize("seed", [2, 3])
def test_default_options_lock_four_separated_modes_at_other_frequencies(seed):
    """5, 12, 30, 80 rad/s (not the paper's), priors ±10 % off, undamped, 50 s: all four locked."""
    w = np.array([5.0, 12.0, 30.0, 80.0])
    prior = w * np.array([1.1, 0.9, 1.1, 0.9])
    est = pll.identify(modes(w, [1, 2, 3, 4], 0.0, DT, 2500, np.random.default_rng(seed)), DT, prior)
    assert est.converged, est.message
    np.testing.assert_array_less(np.abs(est.frequencies - w), 0.005 * w)   # measured: ≤ 0.005 %


def test_default_options_lock_six_octave_spaced_modes():
    """1.5 … 48 rad/s, priors 5–10 % off, 120 s (≈ 3.4 acquisition times of the slowest loop)."""
    w = np.array([1.5, 3.0, 6.0, 12.0, 24.0, 48.0])
    prior = w * np.array([1.08, 0.92, 1.1, 0.9, 1.05, 0.95])
    est = pll.identify(modes(w, [1, 1, 2, 2, 3, 3], 0.0, DT, 6000, np.random.default_rng(4)), DT, prior)
    assert est.converged, est.message
    np.testing.assert_array_less(np.abs(est.frequencies - w), 0.005 * w)   # measured: ≤ 0.03 %


def test_lightly_damped_modes_lock_and_a_mode_that_has_decayed_is_reported_unlocked():
    """ζ = 0.002: modes 1–3 stay locked through 50 s. ζ = 0.005: mode 4 (80 rad/s) decays by e⁻²⁰ and its
    loop runs off; it must say so rather than return a wrong 'locked' frequency."""
    w = np.array([5.0, 12.0, 30.0, 80.0])
    prior = w * np.array([1.1, 0.9, 1.1, 0.9])
    for zeta in (0.002, 0.005):
        wd = w * math.sqrt(1 - zeta**2)
        est = pll.identify(modes(w, [1, 2, 3, 4], zeta, DT, 2500, np.random.default_rng(5)), DT, prior)
        assert all(est.extra["locked"][:3]), est.message
        np.testing.assert_array_less(np.abs(est.frequencies[:3] - wd[:3]), 0.005 * wd[:3])
    assert not est.extra["locked"][3]
    assert abs(est.frequencies[3] - wd[3]) > 0.05 * wd[3]


@pytest.mark.parametrize("remove_mean", [True, False])
def test_sensor_bias_and_a_0_01_s_sample_interval(remove_mean):
    """4, 11, 35 rad/s, ζ = 0.002, priors ±10 % off, 0.5 m/s² bias, 0.01 m/s² noise, Δt = 0.01 s, 60 s.
    The band-pass input filters reject the bias even without mean removal."""
    dt = 0.01
    w = np.array([4.0, 11.0, 35.0])
    wd = w * math.sqrt(1 - 0.002**2)
    y = modes(w, [1, 2, 3], 0.002, dt, 6000, np.random.default_rng(6), noise_m_s2=1e-2, bias_m_s2=0.5)
    est = pll.identify(y, dt, w * np.array([0.9, 1.1, 1.08]), remove_mean=remove_mean)
    assert est.converged, est.message
    np.testing.assert_array_less(np.abs(est.frequencies - wd), 0.005 * wd)  # measured: ≤ 0.015 %


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_capped_input_filters_separate_two_modes_20_percent_apart(seed):
    """20 and 24 rad/s, priors 21 and 23: uncapped 0.5 ω₀ bands (10.5, 11.5 rad/s) both pass both modes and
    neither loop locks; capped at the geometric midpoint (2.1, 2.3 rad/s) each loop locks on its mode."""
    w, prior = np.array([20.0, 24.0]), np.array([21.0, 23.0])
    y = modes(w, [1, 1], 0.0, DT, 2000, np.random.default_rng(seed))
    capped = pll.identify(y, DT, prior)
    uncapped = pll.identify(y, DT, prior, filter_bandwidth_rad_s=list(0.5 * prior))
    assert capped.converged, capped.message
    np.testing.assert_array_less(np.abs(capped.frequencies - w), 0.005 * w)  # measured: ≤ 0.12 %
    assert not any(uncapped.extra["locked"])


def test_default_options_on_hostile_data_do_not_raise_or_claim_lock():
    noise = pll.identify(np.random.default_rng(7).standard_normal(2048), DT, [3.0, 20.0, 60.0])
    assert not any(noise.extra["locked"])
    short = pll.identify(np.random.default_rng(8).standard_normal(20), DT, [3.0, 20.0, 60.0])
    assert not short.converged and short.history.shape == (20, 3)


# --- the derivation rules, against Table 6 --------------------------------------------------------------

def test_derived_loop_bandwidth_is_0_22_prior_close_to_table6():
    """0.616, 3.52, 3.96, 11.44 rad/s vs Table 6's 0.6, 4.0, 4.0, 11.3: within 3 % except loop 2 (−12 %)."""
    wl = default_loop_bandwidth(PRIOR, DT)
    np.testing.assert_allclose(wl, 0.22 * np.array(PRIOR), rtol=1e-12)
    rel = wl / np.array(TABLE6.loop_bandwidth_rad_s) - 1
    assert np.all(np.abs(rel[[0, 2, 3]]) < 0.03) and -0.13 < rel[1] < -0.11
    t_vco = 0.5 / wl                                     # Table 6: 0.8, 0.12, 0.12, 0.045 s
    np.testing.assert_allclose(t_vco, TABLE6.t_vco_s, rtol=0.19)


def test_derived_loop_bandwidth_respects_the_sampling_limits():
    """ω_L Δt ≤ 0.25 (phase margin ≥ 13° with the VCO delay); near Nyquist 0.22 (π/Δt − ω₀) (aliased 2ω₀)."""
    nyq = math.pi / DT
    wl = default_loop_bandwidth([40.0, 80.0, nyq - 10.0], DT)
    np.testing.assert_allclose(wl, [8.8, 0.25 / DT, 2.2])
    for w in wl:
        margins = stability_margins(rule_parameters(w), DT)
        assert margins["phase_margin_deg"] > 13 and margins["gain_margin_db"] > 4.5


def test_an_explicit_loop_bandwidth_alone_gets_the_rule_time_constants():
    """ω_L given, T₁–T₃ and T_VCO left at None: the same loop as design='rule'."""
    y = np.sin(9.0 * np.arange(600) * DT)
    a = pll.identify(y, DT, [8.0], loop_bandwidth_rad_s=[2.0])
    b = pll.identify(y, DT, [8.0], loop_bandwidth_rad_s=[2.0], design="rule",
                     t1_s=[9.9], t2_s=[9.9], t3_s=[9.9], t_vco_s=[9.9])
    np.testing.assert_array_equal(a.history, b.history)


def test_derived_filter_bandwidth_is_half_the_prior_unless_a_neighbour_is_closer():
    """Isolated: 0.5 ω₀ (pass band ≈ ω₀ ± 25 %). Neighbours: bands meet at the prewarped geometric midpoint
    and each filter attenuates the neighbouring centre by ≥ 19 dB."""
    np.testing.assert_allclose(default_filter_bandwidth([7.0], DT), [3.5])
    np.testing.assert_allclose(default_filter_bandwidth([1.0, 2.0, 4.0, 8.0], DT), [0.5, 1.0, 2.0, 4.0])
    centres = [12.0, 14.0, 30.0]
    b = default_filter_bandwidth(centres, DT)
    edges = [band_edges(c, bw, DT) for c, bw in zip(centres, b, strict=True)]
    assert abs(edges[0][1] - edges[1][0]) < 1e-9                   # 12 and 14 meet, ...
    assert edges[1][1] < edges[2][0]                               # 14 and 30 do not need to
    mid = 2 / DT * math.atan(math.sqrt(math.tan(12 * DT / 2) * math.tan(14 * DT / 2)))
    assert abs(edges[0][1] - mid) < 1e-9
    for j, k in [(0, 1), (1, 0)]:
        _, h = scipy.signal.sosfreqz(input_filter_sos(centres[j], b[j], DT), worN=[centres[k] * DT])
        assert 20 * np.log10(abs(h[0])) < -19


def test_derived_filter_bandwidths_for_the_papers_prior_differ_from_table6():
    """Paper prior 2.8, 16, 18, 52: 1.4, 1.89, 2.12, 26 rad/s (Table 6: 5, 9, 9, 12). 16 and 18 are too close
    for 0.5 ω₀ bands; Table 6's overlapping 9 rad/s bands are what the paper blames for loops 2–3."""
    np.testing.assert_allclose(default_filter_bandwidth(PRIOR, DT), [1.4, 1.890, 2.116, 26.0], atol=2e-3)


def test_derived_filter_fits_below_nyquist_and_floors_at_a_tenth_of_the_prior():
    nyq = math.pi / DT
    b = default_filter_bandwidth([nyq - 5.0], DT)[0]
    assert band_edges(nyq - 5.0, b, DT)[1] < nyq - 0.5 + 1e-9     # upper edge ≤ ω₀ + 0.9 (π/Δt − ω₀)
    est = pll.identify(np.sin((nyq - 6.0) * np.arange(500) * DT), DT, [nyq - 5.0])   # designable, runs
    assert np.all(np.isfinite(est.frequencies))
    np.testing.assert_allclose(default_filter_bandwidth([10.0, 10.01], DT), [1.0, 1.001])


def test_method_config_keeps_the_table6_values_for_the_papers_prior():
    from omegaconf import OmegaConf
    cfg = OmegaConf.load(Path(__file__).parents[2] / "configs" / "method" / "pll.yaml")
    assert list(cfg.prior_rad_s) == PRIOR
    for key, value in TABLE6_OPTIONS.items():
        assert list(cfg.options[key]) == value, key
    assert cfg.options.design == "table"
