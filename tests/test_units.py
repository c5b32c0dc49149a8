"""Unit conversions, STIM-300 truth, Table I units, bias-instability WV, Navchip datasheet model."""

import itertools

import numpy as np
import pytest
from scipy.integrate import quad

from gmwm import units as u
from gmwm.errors import InputError, ModelError
from gmwm_studies import sensors as s

# docs/METHODS.md §12.5, "discrete (from Table I)" column (rounded to 5 significant digits there)
EXPECTED = {
    "gyroscope": {"WN[1].sigma2": 1.7118e-3, "RW[1].gamma2": 1.5394e-13},
    "accelerometer": {"QN[1].Q2": 2.0026e-7, "WN[1].sigma2": 1.5340e-4,
                      "RW[1].gamma2": 1.6223e-10, "DR[1].omega": 1.2778e-8},
}


@pytest.mark.parametrize("sensor", ["gyro", "accel"])
def test_stim300_truth_matches_spec_table(sensor):
    truth = s.stim300_truth(sensor)
    exp = EXPECTED[s.canonical_sensor(sensor)]
    assert list(truth) == list(exp)  # canonical order QN, WN, RW, DR
    for k, v in exp.items():
        assert truth[k] == pytest.approx(v, rel=6e-5)  # 5 significant digits, METHODS §12.5


@pytest.mark.parametrize("sensor", ["gyroscope", "accelerometer"])
def test_to_table_units_roundtrips_table_i(sensor):
    truth = s.stim300_truth(sensor)
    for name, value in truth.items():
        ctype = name.split("[")[0]
        table_value, table_unit = s.STIM300_TABLE_I[sensor][ctype]
        assert s.to_table_units(name, value, sensor, 250.0) == pytest.approx(table_value, rel=1e-12)
        assert s.table_unit(name, sensor) == table_unit


def test_hour_conversions_and_inverses():
    assert u.per_sqrt_hour_to_per_sqrt_second(60.0) == 1.0
    assert u.per_hour_sqrt_hour_to_per_second_sqrt_second(216000.0) == 1.0
    assert u.per_hour2_to_per_second2(1.296e7) == 1.0
    f = 200.0
    assert u.qn_coefficient_from_q2(u.qn_q2_from_coefficient(3e-6, f), f) == pytest.approx(3e-6)
    assert u.wn_density_from_sigma2(u.wn_from_density(2e-3, f), f) == pytest.approx(2e-3)
    assert u.rw_coefficient_from_gamma2(u.rw_gamma2_from_coefficient(5e-6, f), f) == pytest.approx(5e-6)
    assert u.dr_coefficient_from_omega(u.dr_omega_from_coefficient(4e-6, f), f) == pytest.approx(4e-6)
    assert u.sin_hz_from_beta(u.sin_beta_from_hz(38.2, f), f) == pytest.approx(38.2)
    assert u.sin_beta_from_hz(f / 2, f) == pytest.approx(np.pi)


def test_gm_ar1_roundtrip():
    phi, s2 = u.gm_to_ar1(0.1, 2.0, 100.0)
    assert phi == pytest.approx(np.exp(-1e-3))
    assert s2 == pytest.approx(2.0 * (1 - np.exp(-2e-3)))
    beta, sgm = u.ar1_to_gm(phi, s2, 100.0)
    assert beta == pytest.approx(0.1) and sgm == pytest.approx(2.0)
    with pytest.raises(InputError):
        u.ar1_to_gm(-0.3, 1.0, 100.0)


def test_bad_inputs_raise():
    with pytest.raises(InputError):
        u.wn_from_density(1e-3, 0.0)
    with pytest.raises(InputError):
        s.to_table_units("WN[1].sigma2", -1.0, "gyro")
    with pytest.raises(InputError):
        s.stim300_truth("magnetometer")
    with pytest.raises(ModelError):
        s.to_table_units("AR1[1].phi", 0.5, "gyro")
    with pytest.raises(ModelError):
        s.to_table_units("WN[1].gamma2", 0.5, "gyro")


def _av_quadrature(b, f0, tau):
    """AV(tau) = 4 int_0^f0 S(f) sin^4(pi f tau)/(pi f tau)^2 df, S = B^2/(2 pi f) (docs/METHODS.md §2.4)."""
    def integrand(f):
        x = np.pi * f * tau
        return 4.0 * b * b / (2.0 * np.pi * f) * np.sin(x) ** 4 / x ** 2

    # split at the zeros of sin(pi f tau) so each piece is smooth
    edges = np.append(np.arange(0.0, f0, 1.0 / tau), f0)
    return sum(quad(integrand, lo, hi, epsabs=0.0, epsrel=1e-12, limit=200)[0]
               for lo, hi in itertools.pairwise(edges))


@pytest.mark.parametrize("tau", [0.004, 0.05, 1.0, 7.3, 100.0])
def test_bias_instability_av_matches_quadrature(tau):
    b, f0 = 4.8e-5, 0.5
    ref = _av_quadrature(b, f0, tau)
    assert s.bias_instability_av(b, f0, tau) == pytest.approx(ref, rel=1e-8)


def test_bias_instability_wv_level_convention_and_limit():
    b, f0, freq = 2.0, 0.5, 250.0
    scales = 2.0 ** np.arange(1, 31)
    wv = s.bias_instability_wv(b, f0, scales, freq)
    # WV at level j is half the AV at cluster time 2^{j-1}/f_s
    assert wv[4] == pytest.approx(s.bias_instability_av(b, f0, 2.0 ** 4 / freq) / 2, rel=1e-14)
    ideal = s.bias_instability_wv_ideal(b, scales)
    assert np.allclose(ideal, np.log(2) / np.pi * b * b)
    # large tau: bracket = ln2 - O(1/x) with x = pi f0 tau; at tau = 2^29/250 s, x ~ 3.4e6
    assert wv[-1] == pytest.approx(ideal[-1], rel=1e-5)
    assert abs(wv[-1] / ideal[-1] - 1) < abs(wv[-10] / ideal[-10] - 1)
    # small tau: flicker cut at f0 is far below ideal
    assert wv[0] < 1e-2 * ideal[0]


@pytest.mark.parametrize("sensor,sigma2", [("gyro", 6.85e-7), ("accel", 6.0e-5)])
def test_navchip_datasheet(sensor, sigma2):
    ds = s.navchip_datasheet(sensor)
    assert ds.components["WN"]["sigma2"] == pytest.approx(sigma2, rel=3e-3)  # README rounding
    assert ds.missing["RW"] == "not given"
    scales = 2.0 ** np.arange(1, 21)
    comp = s.datasheet_wv(ds, scales)
    assert set(comp) == {"WN", "BI", "total"}
    assert np.allclose(comp["total"], comp["WN"] + comp["BI"])
    assert np.allclose(comp["WN"] * scales, ds.components["WN"]["sigma2"])
    ideal = s.datasheet_wv(ds, scales, bi_form="ideal")["BI"]
    assert np.all(comp["BI"] <= ideal * (1 + 1e-12))
    with pytest.raises(InputError):
        s.datasheet_wv(ds, scales, bi_form="flat")


def test_navchip_gyro_bi_in_rad_per_s():
    ds = s.navchip_datasheet("gyroscope")
    assert ds.components["BI"]["B"] == pytest.approx(10.0 / 3600 * np.pi / 180)
    assert ds.unit == "rad/s"
