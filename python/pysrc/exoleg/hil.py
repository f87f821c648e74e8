"""A controller peer of ``exoleg hil`` in pure Python (``socket`` and ``struct`` only): the
protocol of the README's "The controller out of process", the same as ``include/exoleg_hil.h``.

    python -m exoleg.hil HOST PORT            # ERL-SMC with SETUP's parameters (k, delta, zeta)
    python python/pysrc/exoleg/hil.py HOST PORT   # the same without installing the package

or from your code::

    from exoleg.hil import serve
    def make(setup):                  # SETUP: sample_period_s, valve_command_limit, nominal, params
        def step(r):                  # r: the readings by name (r["force_n"], ...)
            return 1e-6 * (r["ref_force_n"] - r["force_n"])    # the valve command
        return step
    serve("127.0.0.1", 9300, make)

A READINGS of a sample already answered (exoleg resends after ``--resend-s``) gets the same
COMMAND again without a second step. This module imports nothing from the compiled package.
"""

import math
import numbers
import socket
import struct
import sys
import time

MAGIC = 0x4C4F5845
VERSION = 1
HELLO, SETUP, READY, READINGS, COMMAND, BYE, REFUSE = range(1, 8)
ABI_VERSION = (1 << 16) | 1
HEADER = struct.Struct("<IHHQQ")
MESSAGE_LEN = 160

# The readings' names in order (EXOLEG_HIL_CHANNELS); their FNV-1a 64 hash goes in HELLO.
CHANNELS = (
    "t_s,period_s,force_n,force_rate_n_per_s,spool_m,piston_m,piston_velocity_m_s,piston_accel_m_s2,"
    "knee_rad,knee_rate_rad_s,ref_force_n,ref_force_rate_n_per_s,ref_force_accel_n_per_s2,"
    "next_ref_force_n,next_ref_force_rate_n_per_s,next_ref_force_accel_n_per_s2,valve_command_limit,"
    "hip_rad,hip_rate_rad_s,thigh_accel_x_m_s2,thigh_accel_y_m_s2,thigh_accel_z_m_s2,"
    "thigh_gyro_x_rad_s,thigh_gyro_y_rad_s,thigh_gyro_z_rad_s,shank_accel_x_m_s2,shank_accel_y_m_s2,"
    "shank_accel_z_m_s2,shank_gyro_x_rad_s,shank_gyro_y_rad_s,shank_gyro_z_rad_s,heel_force_n,"
    "forefoot_force_n,foot_contact,thigh_cuff_force_n,shank_cuff_force_n,pressure_a_pa,pressure_b_pa,"
    "supply_pressure_pa,load_pressure_pa"
).split(",")

# ExolegReadings (544 bytes): size, counts_valid, 17 doubles, counts[5], 23 doubles,
# device_counts_valid, reserved, device_counts[21].
READINGS_STRUCT = struct.Struct("<II17d5q23dII21q")
# COMMAND's payload: status, call, compute_ns, then ExolegCommand (248 bytes).
COMMAND_STRUCT = struct.Struct("<iIQIIdd8d160s")


def channel_hash():
    """FNV-1a 64 of the channel table."""
    h = 0xCBF29CE484222325
    for b in ",".join(CHANNELS).encode():
        h = ((h ^ b) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def _message(kind, seq=0, t_ns=0, payload=b""):
    return HEADER.pack(MAGIC, VERSION, kind, seq, t_ns) + payload


MAX_PARAMS = 256


def parse_setup(b):
    """SETUP's payload as a dict. Anything short, long or lying about its parameters raises
    ValueError naming what is wrong (never struct.error)."""
    if len(b) < 80:
        raise ValueError(f"SETUP truncated: {len(b)} bytes, the fixed part is 80")
    _abi, n, _hash = struct.unpack_from("<IIQ", b, 0)
    if n > MAX_PARAMS:
        raise ValueError(f"SETUP: {n} parameters (at most {MAX_PARAMS})")
    period, limit, n1, n2, n3, tau, ks = struct.unpack_from("<7d", b, 16)
    (seed,) = struct.unpack_from("<Q", b, 72)
    params, at = {}, 80
    for i in range(n):
        if at + 2 > len(b):
            raise ValueError(f"SETUP truncated: parameter {i}'s name length missing")
        (length,) = struct.unpack_from("<H", b, at)
        if at + 2 + length + 8 > len(b):
            raise ValueError(f"SETUP truncated: parameter {i} needs {2 + length + 8} bytes, {len(b) - at} left")
        name = b[at + 2 : at + 2 + length].decode("utf-8", "replace")
        (params[name],) = struct.unpack_from("<d", b, at + 2 + length)
        at += 2 + length + 8
    if at != len(b):
        raise ValueError(f"SETUP oversized: {len(b) - at} bytes after the parameters")
    nominal = {"n1": n1, "n2": n2, "n3": n3, "tau_s": tau, "k_s": ks}
    return {"sample_period_s": period, "valve_command_limit": limit, "nominal": nominal, "seed": seed, "params": params}


def _valve_command(u):
    """The step's return as the valve command: a real number (a bool or a string is refused,
    never converted: "1.5" is not 1.5)."""
    if isinstance(u, bool) or not isinstance(u, numbers.Real):
        raise TypeError(f"step() must return the valve command as a number, got {u!r} ({type(u).__name__})")
    return float(u)


def parse_readings(b):
    """READINGS' payload as a dict of the channels by name."""
    v = READINGS_STRUCT.unpack(b)
    doubles = v[2:19] + v[24:47]
    return dict(zip(CHANNELS, doubles))


def erl_smc(setup):
    """ERL-SMC in the order of exoleg's built-in (and examples/c_controller/erl_smc.c)."""
    p, n = setup["params"], setup["nominal"]
    k, delta, zeta = p.get("k", 100.0), p.get("delta", 15.0), p.get("zeta", 10.0)

    def step(r):
        e = r["ref_force_n"] - r["force_n"]
        e_dot = r["ref_force_rate_n_per_s"] - r["force_rate_n_per_s"]
        s = e_dot + delta * e
        accel = r["ref_force_accel_n_per_s2"] + delta * e_dot + k * s + zeta * math.tanh(s)
        return n["tau_s"] / (n["n1"] * n["k_s"]) * (
            accel + n["n3"] * r["force_rate_n_per_s"] + n["n2"] * r["piston_accel_m_s2"] + n["n1"] * r["spool_m"] / n["tau_s"]
        )

    return step


def _handshake(sock, timeout_s):
    hello = _message(HELLO, payload=struct.pack("<IIQ", ABI_VERSION, 0, channel_hash()))
    t0 = time.monotonic()
    sock.settimeout(0.2)
    while time.monotonic() - t0 < timeout_s:
        sock.send(hello)
        try:
            b = sock.recv(65536)
        except (socket.timeout, ConnectionRefusedError):
            time.sleep(0.05)
            continue
        if len(b) < HEADER.size:
            continue
        magic, version, kind, _seq, _t = HEADER.unpack_from(b)
        if magic != MAGIC or version != VERSION:
            continue
        if kind == REFUSE:
            raise RuntimeError("exoleg refused: " + b[HEADER.size + 8 :].split(b"\0")[0].decode("utf-8", "replace"))
        if kind == SETUP:
            return parse_setup(b[HEADER.size :])
    raise TimeoutError(f"no SETUP from exoleg in {timeout_s} s")


def serve(host, port, make, timeout_s=30.0):
    """Connect to ``exoleg hil`` at host:port, build ``step = make(setup)``, answer every sample
    with ``step(readings)`` (the valve command) until BYE. Returns the number of samples."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.connect((host, int(port)))
    setup = _handshake(sock, timeout_s)
    step = make(setup)
    sock.send(_message(READY, payload=struct.pack("<iI", 0, 0) + bytes(MESSAGE_LEN)))
    sock.settimeout(timeout_s)
    last_seq, last_reply, samples = None, None, 0
    while True:
        b = sock.recv(65536)
        if len(b) < HEADER.size:
            continue
        magic, version, kind, seq, t_ns = HEADER.unpack_from(b)
        if magic != MAGIC or version != VERSION:
            continue
        if kind == BYE:
            return samples
        if kind != READINGS or len(b) != HEADER.size + READINGS_STRUCT.size:
            continue
        if seq == last_seq:
            sock.send(last_reply)
            continue
        t0 = time.perf_counter_ns()
        u = _valve_command(step(parse_readings(b[HEADER.size :])))
        compute_ns = time.perf_counter_ns() - t0
        payload = COMMAND_STRUCT.pack(0, 0, compute_ns, 248, 0, u, 0.0, *([0.0] * 8), b"")
        last_seq, last_reply = seq, _message(COMMAND, seq, t_ns, payload)
        sock.send(last_reply)
        samples += 1


def main(argv):
    usage = "usage: python -m exoleg.hil HOST PORT"
    if len(argv) != 3:
        print(usage, file=sys.stderr)
        return 2
    try:
        port = int(argv[2])
        if not 0 < port < 65536:
            raise ValueError
    except ValueError:
        print(f"error: PORT: {argv[2]!r} is not a port number (1..65535); {usage}", file=sys.stderr)
        return 2
    try:
        n = serve(argv[1], port, erl_smc)
    except (OSError, ValueError, RuntimeError, TimeoutError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 3
    print(f"samples {n}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
