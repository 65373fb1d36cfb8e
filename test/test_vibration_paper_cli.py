"""``stewart-vibration paper --out DIR`` writes the figures, JSON and markdown.

The JSON numbers are checked against the independent references of
``vibration_reference`` (hinges rebuilt from robot.yaml, per-leg loops) and
the corrected closed forms (k_i = n_i . u, X = a / (2 pi f)^2, second
harmonic and DC (1 - k^2) A^2 / (4 l), naive sum = N^T N u delta), not
against another output of the same code.
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest
from vibration_reference import jacobian_ref, line_angle, rpy_matrix

from stewart_vibration.cli.main import main

G = 9.80665  # standard gravity, m/s^2
PAPER_OFFSET = np.array([0.002, 0.002, 0.002, np.pi / 15, np.pi / 12, np.pi / 18])  # paper section 4.2
CASES = {  # amplitude (m), frequency (Hz), phase (rad): the paper's 0.001 sin(2 t + 2 pi / 3) mm; 35 Hz at 0.3 g
    "paper_example": (1e-6, 2.0 / (2 * np.pi), 2 * np.pi / 3),
    "clinical": (0.3 * G / (2 * np.pi * 35.0) ** 2, 35.0, 2 * np.pi / 3),
}


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper")
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert main(["paper", "--out", str(out)]) == 0
    assert f"written to {out}" in printed.getvalue()
    return out, json.loads((out / "vibration_paper.json").read_text())


def test_paper_command_writes_figures_and_tables(report):
    out, data = report
    assert len(data["figures"]) == 6
    for name in data["figures"]:
        png = (out / name).read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    assert [data["fig7"][k]["exact"]["kind"] for k in ("7a", "7b", "7c")] == ["lissajous", "ellipse", "line"]
    md = (out / "vibration_paper.md").read_text()
    assert "| 7b |" in md and "naive" in md


@pytest.mark.parametrize("case", sorted(CASES))
def test_decomposition_numbers_match_the_closed_forms(robot, report, case):
    amplitude, frequency, phase = CASES[case]
    c = report[1][case]
    pose = robot.home_pose + PAPER_OFFSET
    np.testing.assert_allclose(report[1]["pose"], pose, rtol=0, atol=1e-15)
    _, lengths, n = jacobian_ref(robot, pose)
    u = rpy_matrix(*pose[3:])[:, 2]  # force line = platform z axis
    k = n @ u
    assert c["amplitude_m"] == pytest.approx(amplitude, rel=1e-15)
    assert c["frequency_hz"] == pytest.approx(frequency, rel=1e-15)
    np.testing.assert_allclose(c["direction_base"], u, rtol=0, atol=1e-15)
    np.testing.assert_allclose(c["nominal_lengths_m"], lengths, rtol=0, atol=1e-15)
    np.testing.assert_allclose(c["gains"], k, rtol=0, atol=1e-12)
    np.testing.assert_allclose(c["leg_amplitudes_m"], np.abs(k) * amplitude, rtol=1e-12)
    expected_phase = np.where(k < 0, phase + np.pi, phase) % (2 * np.pi)
    np.testing.assert_allclose(c["leg_phases_rad"], expected_phase, rtol=0, atol=1e-12)
    # FFT of the exact IK signals: the next terms are relative (A / l)^2 <= 2e-7 (61 um on 0.14 m)
    np.testing.assert_allclose(c["fft_fundamental_m"], np.abs(k) * amplitude, rtol=1e-6)
    second = (1 - k**2) * amplitude**2 / (4 * lengths)
    np.testing.assert_allclose(c["fft_second_harmonic_m"], second, rtol=2e-6)
    np.testing.assert_allclose(c["fft_dc_m"], second, rtol=2e-6)
    np.testing.assert_allclose(c["predicted_second_harmonic_ratio"], second / (np.abs(k) * amplitude), rtol=1e-12)
    # peak leg acceleration |k| A (2 pi f)^2, up to the second-order term (relative ~ A / l)
    w = 2 * np.pi * frequency
    np.testing.assert_allclose(c["peak_leg_acceleration_m_s2"], np.abs(k) * amplitude * w * w,
                               rtol=3 * amplitude / lengths.min())
    assert c["second_order_residual_ratio"] < 0.05
    assert c["roundtrip_angle_linear_rad"] < 1e-6 and c["roundtrip_rotation_linear_rad"] < 1e-15


def test_naive_sum_matches_its_closed_form(robot, report):
    """The paper's sum_i n_i dl_i with dl_i = k_i delta = (n_i . u) delta is N^T N u delta: its length
    ratio to the true motion u delta is |N^T N u| and its angle that of N^T N u to u."""
    pose = robot.home_pose + PAPER_OFFSET
    _, _, n = jacobian_ref(robot, pose)
    rot = rpy_matrix(*pose[3:])
    naive = report[1]["naive_vs_jacobian"]
    platform_dirs = {"platform z (tibia axis)": [0, 0, 1], "platform x": [1, 0, 0], "platform y": [0, 1, 0],
                     "platform [1, 1, 1]": [1, 1, 1]}
    assert sorted(naive) == sorted(platform_dirs)
    for label, d in platform_dirs.items():
        u = rot @ np.array(d, float) / np.linalg.norm(d)
        wrong = n.T @ (n @ u)
        v = naive[label]
        assert line_angle(v["direction_base"], u) < 1e-12
        assert v["length_ratio"] == pytest.approx(np.linalg.norm(wrong), rel=1e-12)
        assert v["angle_error_deg"] == pytest.approx(np.degrees(line_angle(wrong, u)), abs=1e-9)
        assert line_angle(v["naive_direction_base"], wrong) < 1e-12
    tibia = naive["platform z (tibia axis)"]
    assert tibia["length_ratio"] > 1.5 and tibia["angle_error_deg"] > 5  # visibly wrong (the paper's error)
