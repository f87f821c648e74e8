"""The pure-Python HIL peer (issue 36): exoleg hil in lockstep against exoleg.hil's ERL-SMC gives
the built-in ERL-SMC's time series at 1 kHz, bit for bit."""

import os
import subprocess
import sys
import threading

import exoleg.hil

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("EXOLEG_BIN", os.path.join(ROOT, "target", "release", "exoleg"))
SC = os.path.join(ROOT, "assets", "scenarios", "paper_2hz_gamma100.toml")
SETS = ["controller.sample_period_s=0.001", "controller.plugin.params={k=100.0, delta=15.0, zeta=10.0}",
        "sensors.preset=\"adc16\"", "sensors.delay_samples=1"]


def _args(extra):
    out = []
    for s in SETS + extra:
        out += ["--set", s]
    return out


def test_python_peer_in_lockstep_equals_the_builtin(tmp_path):
    builtin = tmp_path / "builtin"
    r = subprocess.run([BIN, "run", "--quiet", "--out", str(builtin), SC] + _args(['controller.kind="erl_smc"']),
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    hil = tmp_path / "hil"
    p = subprocess.Popen([BIN, "hil", SC, "--quiet", "--listen", "127.0.0.1:0", "--out", str(hil)] + _args([]),
                         stderr=subprocess.PIPE, text=True)
    line = p.stderr.readline()
    port = int(line.strip().rsplit(":", 1)[1].split(" ")[0])
    threading.Thread(target=p.stderr.read, daemon=True).start()
    assert exoleg.hil.serve("127.0.0.1", port, exoleg.hil.erl_smc) == 1000
    assert p.wait(timeout=60) == 0
    assert (hil / "timeseries.csv").read_bytes() == (builtin / "timeseries.csv").read_bytes()


def test_channel_hash_is_the_headers():
    assert exoleg.hil.channel_hash() == 0x81E8CFBCCC610C3C
    assert exoleg.hil.READINGS_STRUCT.size == 544
    assert exoleg.hil.COMMAND_STRUCT.size == 16 + 248
