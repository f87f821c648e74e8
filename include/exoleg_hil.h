/*
 * exoleg_hil.h: a controller peer of exoleg over UDP (hardware in the loop), wrapping any
 * plugin's exoleg_create / exoleg_reset / exoleg_step / exoleg_destroy, so the same firmware
 * source runs as a plugin, as an isolated plugin, or as a peer on a board or another machine.
 * The implementation is examples/hil/exoleg_hil.c (libc and POSIX sockets only).
 *
 * The protocol (the README's "The controller out of process" has the byte table): every
 * message is one datagram, little-endian: a 24-byte header
 *     0 magic u32 = EXOLEG_HIL_MAGIC ("EXOL")   4 version u16   6 type u16
 *     8 seq u64 (the sample index)              16 simulated time u64 (ns)
 * then the payload of its type:
 *     peer -> exoleg  HELLO     abi_version u32, reserved u32, channel_hash u64
 *     exoleg -> peer  SETUP     abi_version u32, n_params u32, channel_hash u64,
 *                               sample_period_s, valve_command_limit, n1, n2, n3, tau_s, k_s
 *                               (f64), seed u64, n_params x {name_len u16, name, value f64}
 *     peer -> exoleg  READY     status i32 (0 created, 2 refused), reserved u32, message[160]
 *     exoleg -> peer  READINGS  ExolegReadings (exoleg_controller.h), as it is in memory
 *     peer -> exoleg  COMMAND   status i32, call u32 (0 step, 1 reset), compute_ns u64,
 *                               ExolegCommand
 *     exoleg -> peer  BYE / REFUSE  status i32, reserved u32, message[160]
 * The structs are sent as they lie in memory: a big-endian target swaps every field.
 * READINGS of a sample already answered (exoleg resends after --resend-s) get the same
 * COMMAND again, without a second step. The protocol is unauthenticated: exoleg takes the
 * first peer that says HELLO (from an address `--allow-from` allows) and from then on drops
 * every datagram from anyone else.
 */
#ifndef EXOLEG_HIL_H
#define EXOLEG_HIL_H

#include <stddef.h>
#include <stdint.h>

#include "exoleg_controller.h"

#ifdef __cplusplus
extern "C" {
#endif

#define EXOLEG_HIL_MAGIC 0x4C4F5845u
#define EXOLEG_HIL_VERSION 1
#define EXOLEG_HIL_HEADER_LEN 24
#define EXOLEG_HIL_MAX_DATAGRAM 32768

#define EXOLEG_HIL_HELLO 1
#define EXOLEG_HIL_SETUP 2
#define EXOLEG_HIL_READY 3
#define EXOLEG_HIL_READINGS 4
#define EXOLEG_HIL_COMMAND 5
#define EXOLEG_HIL_BYE 6
#define EXOLEG_HIL_REFUSE 7

/* The channel table: the readings' names in order, joined by ','. Its FNV-1a 64 hash
   (exoleg_hil_channel_hash) goes in HELLO; exoleg refuses another table. */
#define EXOLEG_HIL_CHANNELS                                                                      \
    "t_s,period_s,force_n,force_rate_n_per_s,spool_m,piston_m,piston_velocity_m_s,"              \
    "piston_accel_m_s2,knee_rad,knee_rate_rad_s,ref_force_n,ref_force_rate_n_per_s,"             \
    "ref_force_accel_n_per_s2,next_ref_force_n,next_ref_force_rate_n_per_s,"                     \
    "next_ref_force_accel_n_per_s2,valve_command_limit,hip_rad,hip_rate_rad_s,"                  \
    "thigh_accel_x_m_s2,thigh_accel_y_m_s2,thigh_accel_z_m_s2,thigh_gyro_x_rad_s,"               \
    "thigh_gyro_y_rad_s,thigh_gyro_z_rad_s,shank_accel_x_m_s2,shank_accel_y_m_s2,"               \
    "shank_accel_z_m_s2,shank_gyro_x_rad_s,shank_gyro_y_rad_s,shank_gyro_z_rad_s,heel_force_n,"  \
    "forefoot_force_n,foot_contact,thigh_cuff_force_n,shank_cuff_force_n,pressure_a_pa,"         \
    "pressure_b_pa,supply_pressure_pa,load_pressure_pa"

/* The plugin's entry points (statically linked, or from dlsym). */
typedef struct ExolegHilPlugin {
    void *(*create)(const ExolegInfo *info);
    int32_t (*reset)(void *instance);
    int32_t (*step)(void *instance, const ExolegReadings *readings, ExolegCommand *command);
    void (*destroy)(void *instance);
} ExolegHilPlugin;

/* Test knobs (all 0: a plain peer). */
typedef struct ExolegHilOptions {
    double timeout_s;         /* give up after this long without a message (s); 0 = 30 */
    double sleep_probability; /* before a reply, sleep with this probability ... */
    double sleep_max_s;       /* ... a uniform 0..sleep_max_s (s) */
    double drop_probability;  /* drop a COMMAND (not sent) with this probability */
    uint64_t seed;            /* of the knobs' random draws */
} ExolegHilOptions;

/* What the peer did. */
typedef struct ExolegHilStats {
    uint64_t samples;  /* READINGS of a new sample */
    uint64_t repeats;  /* READINGS of a sample already answered (answered again) */
    uint64_t dropped;  /* COMMANDs not sent (drop_probability) */
    uint64_t slept;    /* replies delayed (sleep_probability) */
    uint64_t malformed; /* datagrams that did not decode (ignored) */
} ExolegHilStats;

/* FNV-1a 64 of EXOLEG_HIL_CHANNELS. */
uint64_t exoleg_hil_channel_hash(void);

/* Connect to exoleg at host:port, say HELLO, create the instance from SETUP, answer every
   READINGS until BYE. Returns 0 after BYE, else -1 with the reason in err. */
int exoleg_hil_run(const char *host, const char *port, const ExolegHilPlugin *plugin,
                   const ExolegHilOptions *options, ExolegHilStats *stats, char *err, size_t err_len);

#ifdef __cplusplus
}
#endif

#endif /* EXOLEG_HIL_H */
