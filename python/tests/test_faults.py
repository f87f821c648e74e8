"""The fault campaign from Python (issue 35): exoleg.faults matches the CLI's faults.csv, takes a
Python controller (which may read the device's channels), and runs on Dask identically."""

import os
import subprocess

import pytest

import exoleg

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("EXOLEG_BIN", os.path.join(ROOT, "target", "release", "exoleg"))
SCENARIO = os.path.join(ROOT, "assets", "scenarios", "gait_treadmill.toml")
OVERRIDES = {"leg.engine": "reduced", "sim.dt_s": 0.001}
MATRIX = """onsets_pct = [0.0, 50.0]
[[mode]]
target = "force_n"
kind = "bias"
[[mode.severity]]
label = "100 N"
bias = 100.0
[[mode]]
target = "valve"
kind = "stuck"
[[mode.severity]]
label = "where it is"
"""


def _matrix(tmp_path):
    p = tmp_path / "matrix.toml"
    p.write_text(MATRIX)
    return p


def test_faults_matches_the_cli_and_dask(tmp_path):
    m = _matrix(tmp_path)
    study = exoleg.faults(SCENARIO, matrix=m, overrides=OVERRIDES, out=tmp_path / "py", jobs=2)
    assert len(study.runs()) == 5
    p = subprocess.run([BIN, "faults", SCENARIO, "--set", 'leg.engine="reduced"', "--set", "sim.dt_s=0.001",
                        "--matrix", str(m), "--quiet", "--out", str(tmp_path / "cli")], capture_output=True, text=True)
    assert p.returncode in (0, 4), p.stderr
    for f in ("faults.csv", "runs.jsonl", "fmea.md"):
        assert (tmp_path / "py" / f).read_bytes() == (tmp_path / "cli" / f).read_bytes(), f
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        with distributed.Client(cl) as client:
            exoleg.distributed.faults(client, SCENARIO, matrix=m, overrides=OVERRIDES, out=tmp_path / "dask")
    assert (tmp_path / "dask" / "faults.csv").read_bytes() == (tmp_path / "py" / "faults.csv").read_bytes()


def test_faults_with_a_python_controller_and_bad_input(tmp_path):
    # A transparent controller (command 0) that reads the heel sensor: the default matrix then
    # faults heel_force_n and shank_gyro_y_rad_s too.
    seen = []

    def ctrl(obs):
        seen.append(obs.heel_force_n)
        return 0.0

    m = tmp_path / "m.toml"
    m.write_text('onsets_pct = [20.0]\n[[mode]]\ntarget = "heel_force_n"\nkind = "stuck"\n'
                 '[[mode.severity]]\nlabel = "at 0"\nvalue = 0.0\n')
    study = exoleg.faults(SCENARIO, matrix=m, overrides={**OVERRIDES, "controller.sample_period_s": 0.001},
                          out=tmp_path / "c", controller=ctrl)
    assert len(study.runs()) == 2 and len(seen) > 1000
    assert (tmp_path / "c" / "faults.csv").exists()
    m.write_text("onsets_pct = [20.0]\n")
    with pytest.raises(exoleg.ScenarioError, match="no fault"):
        exoleg.faults(SCENARIO, matrix=m, overrides=OVERRIDES, out=tmp_path / "e")
    assert not (tmp_path / "e").exists()
