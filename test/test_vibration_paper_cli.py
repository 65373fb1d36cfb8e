"""``stewart-vibration paper --out DIR`` writes the figures, JSON and markdown (issue 3)."""

from __future__ import annotations

import json

import numpy as np

from stewart_vibration.cli.main import main


def test_paper_command_writes_figures_and_tables(tmp_path, capsys):
    assert main(["paper", "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "vibration_paper.json").read_text())
    for name in report["figures"]:
        data = (tmp_path / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
    assert len(report["figures"]) == 6
    assert [report["fig7"][k]["exact"]["kind"] for k in ("7a", "7b", "7c")] == ["lissajous", "ellipse", "line"]
    for case in ("paper_example", "clinical"):
        c = report[case]
        assert c["second_order_residual_ratio"] < 0.05
        np.testing.assert_allclose(c["fft_fundamental_m"], c["leg_amplitudes_m"], rtol=1e-6)
        assert c["roundtrip_angle_linear_rad"] < 1e-6 and c["roundtrip_rotation_linear_rad"] < 1e-15
    assert report["clinical"]["amplitude_m"] == np.float64(0.3 * 9.80665 / (2 * np.pi * 35) ** 2)
    naive = report["naive_vs_jacobian"]["platform z (tibia axis)"]
    assert naive["length_ratio"] > 1.5 and naive["angle_error_deg"] > 5
    md = (tmp_path / "vibration_paper.md").read_text()
    assert "| 7b |" in md and "naive" in md
    assert "written to" in capsys.readouterr().out
