"""Issue 42 through the Python package: a raising controller under a campaign's failsafe is never
"detected" and its exception is kept (class 1); exoleg.distributed.faults refuses a shard count
that means nothing and exoleg.hil.serve a step's string (class 10); exoleg.hil says what is wrong
with a hostile SETUP and a bad PORT instead of a struct.error or a traceback (class 11)."""

import csv
import os
import socket
import struct
import subprocess
import sys
import threading

import pytest

import exoleg
from exoleg import hil

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
LEG = os.path.join(ROOT, "assets", "scenarios", "default.toml")
SAMPLED = {
    "controller.sample_period_s": 0.001,
    "sim.duration_s": 0.6,
    "actuator.failsafe": "free",
    "actuator.spool_limit_m": 0.001,
}
MATRIX = 'onsets_s = [0.3, 0.4]\n[[mode]]\ntarget = "power"\nkind = "loss"\n[[mode.severity]]\nlabel = "50 ms"\nduration_s = 0.05\n'


def test_a_raising_controller_is_never_detected_in_a_campaign(tmp_path):
    m = tmp_path / "m.toml"
    m.write_text(MATRIX)

    def ctrl(obs):
        if obs.t_s >= 0.1:
            raise RuntimeError("the firmware's bug")
        return 0.0

    exoleg.faults(LEG, matrix=m, overrides=SAMPLED, out=tmp_path / "c", controller=ctrl)
    rows = list(csv.DictReader(open(tmp_path / "c" / "faults.csv")))
    assert len(rows) == 3
    for r in rows:
        assert r["status"] == "crashed", r
        assert "the firmware's bug" in r["error"], r
        assert r["time_to_detection_s"] == "", r
    assert [r["fault_onset_s"] for r in rows[1:]] == ["0.3", "0.4"]
    fmea = (tmp_path / "c" / "fmea.md").read_text()
    assert "| 0/2 |" in fmea and "the baseline's own controller crashed" in fmea, fmea


def test_distributed_faults_refuses_a_shard_count_that_means_nothing(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    m = tmp_path / "m.toml"
    m.write_text(MATRIX)
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=None) as client:
        for bad in (-5, 0, 1.5, "2"):
            with pytest.raises(exoleg.ScenarioError, match="shards"):
                exoleg.distributed.faults(client, LEG, matrix=m, overrides=SAMPLED, out=tmp_path / "d", shards=bad)


def _fake_exoleg(reply):
    """A UDP socket standing for exoleg: answers the first HELLO with `reply` (bytes)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))

    def serve():
        s.settimeout(10)
        try:
            _, peer = s.recvfrom(65536)
            s.sendto(reply, peer)
        except OSError:
            pass

    threading.Thread(target=serve, daemon=True).start()
    return s, s.getsockname()[1]


def _setup(params_bytes, n):
    fixed = struct.pack("<IIQ", hil.ABI_VERSION, n, hil.channel_hash()) + struct.pack("<7d", *([1e-3] + [1.0] * 6))
    fixed += struct.pack("<Q", 7)
    return hil._message(hil.SETUP, payload=fixed + params_bytes)


@pytest.mark.parametrize(
    "payload,n,want",
    [
        (b"", 3, "truncated"),  # says 3 parameters, has none
        (struct.pack("<H", 200) + b"abc", 1, "truncated"),  # a name longer than what is left
        (struct.pack("<H", 1) + b"k" + struct.pack("<d", 1.0) + b"junk", 1, "oversized"),
        (b"", 100000, "parameters"),
    ],
)
def test_serve_says_what_is_wrong_with_a_hostile_setup(payload, n, want):
    s, port = _fake_exoleg(_setup(payload, n))
    with s:
        with pytest.raises(ValueError, match=want):
            hil.serve("127.0.0.1", port, lambda setup: (lambda r: 0.0), timeout_s=5.0)


def test_parse_setup_of_truncated_bytes_raises_value_error():
    for cut in range(0, 80, 7):
        with pytest.raises(ValueError):
            hil.parse_setup(b"\0" * cut)


def test_a_steps_string_is_refused_not_converted():
    assert hil._valve_command(1) == 1.0 and hil._valve_command(1.5) == 1.5
    for bad in ("1.5", True, None, [1.0]):
        with pytest.raises(TypeError, match="valve command"):
            hil._valve_command(bad)


def test_a_bad_port_is_exit_2_without_a_traceback():
    script = os.path.join(ROOT, "python", "pysrc", "exoleg", "hil.py")
    for port in ("abc", "0", "70000"):
        p = subprocess.run([sys.executable, script, "127.0.0.1", port], capture_output=True, text=True, timeout=30)
        assert p.returncode == 2, p.stderr
        assert "Traceback" not in p.stderr and "PORT" in p.stderr, p.stderr
