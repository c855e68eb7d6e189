"""The pure-rotation slip study (Fig. 16-18) and its command."""

import math

import pytest
from click.testing import CliRunner

from pushtrain.cli.main import cli
from pushtrain.studies.slipstudy import SlipStudyConfig, run_slip_study

INERTIA, D = 3.5083, 0.52


@pytest.fixture(scope="module")
def rows():
    cfg = SlipStudyConfig(trailers=(1, 2, 4), alphas_deg=(5.0, 20.0, 40.0), n_for_alpha=3,
                          n_for_payload=3)
    return run_slip_study(cfg)


def test_forces_grow_with_n_and_alpha_and_start_at_the_spin_up_closed_form(rows):
    by_n = {r.n: r for r in rows if r.sweep == "trailers"}
    assert by_n[1].peak[0] < by_n[2].peak[0] < by_n[4].peak[0]
    by_alpha = [r.peak[0] for r in rows if r.sweep == "alpha"]
    assert by_alpha == sorted(by_alpha)
    for n, r in by_n.items():  # at rest the robot spins up: F_d,1 = I alpha / D (1 + 2 (n - 1))
        spin_up = INERTIA * math.radians(5.0) / D * (1 + 2 * (n - 1))
        assert r.peak[0] >= spin_up * (1 - 1e-9)
    # trailer 1 carries the largest lateral force (paper, Sec. 4.4)
    for r in rows:
        if r.sweep != "payload":
            assert r.peak[0] == pytest.approx(max(r.peak))


def test_payload_on_the_last_trailer_loads_trailer_1_most(rows):
    payload = sorted((r for r in rows if r.sweep == "payload"), key=lambda r: r.payload_on)
    peaks = [r.peak[0] for r in payload]
    assert peaks[-1] == max(peaks) and peaks[0] == min(peaks)
    assert payload[0].limit[0] == pytest.approx(0.09 * (42.1 + 80.0) * 9.81)


def test_slip_study_command_writes_table_and_plot(tmp_path):
    out = tmp_path / "slip"
    result = CliRunner().invoke(cli, ["slip-study", "--trailers", "1,2", "--alphas", "5,30",
                                      "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert (out / "slip_study.png").stat().st_size > 10_000
    lines = (out / "slip_study.csv").read_text().splitlines()
    assert lines[0].startswith("sweep,n,alpha_deg") and len(lines) == 1 + (1 + 2) + (3 + 3) + 9
    bad = CliRunner().invoke(cli, ["slip-study", "--trailers", "0", "--out", str(out)])
    assert bad.exit_code == 2 and "trailers" in bad.output


@pytest.mark.parametrize("trailers", [(0,), (1, 51), (-3, 2), ()])
def test_trailer_counts_outside_1_to_50_are_refused(trailers):
    from pushtrain.studies.slipstudy import SlipStudyConfig

    with pytest.raises(ValueError, match=r"trailers = .*each must be 1\.\.50"):
        SlipStudyConfig(trailers=trailers)
    assert SlipStudyConfig(trailers=(1, 50)).trailers == (1, 50)
