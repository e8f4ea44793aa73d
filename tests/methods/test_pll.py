"""Phase-locked-loop bank (paper §3.4, §4.4, Table 6): lock, acquisition, design rule, input filters."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal

from methods import pll
from methods.pll_design import (
    LoopParameters,
    band_edges,
    input_filter_sos,
    loop_time_constants,
    omega_l_from_time_constants,
    open_loop_response,
    stability_margins,
)

DT = 0.02
TRUE = [3.23, 20.24, 22.00, 56.67]                 # Table 6 "True frequency"
PRIOR = [2.80, 16.00, 18.00, 52.00]                # Table 6 "A priori frequency"
TABLE6 = pll.Options()                             # the defaults are Table 6
AMPLITUDE = [1.06, 3.90, 5.12, 6.47]               # PHYSICS.md §3, coupled model, m/s²


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
    est = pll.identify(tip_like(2048), DT, PRIOR, output_window_s=10.0)
    assert est.history.shape == (2048, 4)
    assert est.extra["locked"][0]
    for j in (0, 3):
        assert abs(est.frequencies[j] - TRUE[j]) < 0.005 * TRUE[j]
    assert not est.converged                   # the 1.76 rad/s beat of modes 2 and 3 breaks their lock


# --- records the loops cannot lock on ------------------------------------------------------------------

@pytest.mark.parametrize("n", [20, 32, 64, 128, 256])
def test_short_records_are_reported_not_converged_without_exception(n):
    """0.4–5 s: shorter than (or barely as long as) the acquisition times 21, 3.1, 3.1, 1.1 s."""
    est = pll.identify(tip_like(n, np.random.default_rng(1), 1e-2), DT, PRIOR)
    assert not est.converged
    assert est.history.shape == (n, 4)
    assert np.all(np.isfinite(est.frequencies))
    assert not est.extra["locked"][0]
    assert "loop 1 (2.8 rad/s) not locked" in est.message


def test_pure_noise_is_not_reported_as_locked():
    est = pll.identify(np.random.default_rng(2).standard_normal(2048), DT, PRIOR)
    assert not est.converged
    assert not any(est.extra["locked"])


def test_identically_zero_record_fails_cleanly():
    est = pll.identify(np.zeros(100), DT, PRIOR)
    assert not est.converged
    assert np.all(np.isnan(est.frequencies))


def test_huge_noise_does_not_raise():
    est = pll.identify(tip_like(512, np.random.default_rng(3), 1e3), DT, PRIOR)
    assert est.history.shape == (512, 4)
    assert np.all((est.history > 0) & (est.history < math.pi / DT))


def test_invalid_options_raise_value_error():
    with pytest.raises(ValueError, match="unknown option"):
        pll.identify(np.ones(100), DT, PRIOR, bandwidth=3.0)
    with pytest.raises(ValueError, match="gain has 3 entries"):
        pll.identify(np.ones(100), DT, PRIOR, gain=[1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="design"):
        pll.identify(np.ones(100), DT, PRIOR, design="magic")


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
    est = pll.identify(tip_like(64), DT, PRIOR)
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
