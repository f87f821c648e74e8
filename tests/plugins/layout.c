/* Prints the size and every field offset of the ABI's structs, as the header defines them,
   for tests/it/your_controller.rs to compare with the Rust #[repr(C)] structs. */
#include <stddef.h>
#include <stdio.h>
#include "exoleg_controller.h"
#define F(T, f) printf(#T "." #f " %zu\n", offsetof(T, f))
int main(void) {
    printf("ExolegParam %zu\nExolegInfo %zu\nExolegReadings %zu\nExolegCommand %zu\n", sizeof(ExolegParam),
           sizeof(ExolegInfo), sizeof(ExolegReadings), sizeof(ExolegCommand));
    F(ExolegParam, name); F(ExolegParam, value);
    F(ExolegInfo, size); F(ExolegInfo, abi_version); F(ExolegInfo, sample_period_s);
    F(ExolegInfo, valve_command_limit); F(ExolegInfo, nominal_n1); F(ExolegInfo, nominal_n2);
    F(ExolegInfo, nominal_n3); F(ExolegInfo, nominal_tau_s); F(ExolegInfo, nominal_k_s); F(ExolegInfo, seed);
    F(ExolegInfo, n_params); F(ExolegInfo, reserved); F(ExolegInfo, params);
    F(ExolegReadings, size); F(ExolegReadings, counts_valid); F(ExolegReadings, t_s); F(ExolegReadings, period_s);
    F(ExolegReadings, force_n); F(ExolegReadings, force_rate_n_per_s); F(ExolegReadings, spool_m);
    F(ExolegReadings, piston_m); F(ExolegReadings, piston_velocity_m_s); F(ExolegReadings, piston_accel_m_s2);
    F(ExolegReadings, knee_rad); F(ExolegReadings, knee_rate_rad_s); F(ExolegReadings, ref_force_n);
    F(ExolegReadings, ref_force_rate_n_per_s); F(ExolegReadings, ref_force_accel_n_per_s2);
    F(ExolegReadings, next_ref_force_n); F(ExolegReadings, next_ref_force_rate_n_per_s);
    F(ExolegReadings, next_ref_force_accel_n_per_s2); F(ExolegReadings, valve_command_limit);
    F(ExolegReadings, counts);
    F(ExolegReadings, hip_rad); F(ExolegReadings, hip_rate_rad_s); F(ExolegReadings, thigh_accel_m_s2);
    F(ExolegReadings, thigh_gyro_rad_s); F(ExolegReadings, shank_accel_m_s2); F(ExolegReadings, shank_gyro_rad_s);
    F(ExolegReadings, heel_force_n); F(ExolegReadings, forefoot_force_n); F(ExolegReadings, foot_contact);
    F(ExolegReadings, thigh_cuff_force_n); F(ExolegReadings, shank_cuff_force_n); F(ExolegReadings, pressure_a_pa);
    F(ExolegReadings, pressure_b_pa); F(ExolegReadings, supply_pressure_pa); F(ExolegReadings, load_pressure_pa);
    F(ExolegReadings, device_counts_valid); F(ExolegReadings, reserved1); F(ExolegReadings, device_counts);
    printf("EXOLEG_ABI_VERSION %u\n", (unsigned)EXOLEG_ABI_VERSION);
    F(ExolegCommand, size); F(ExolegCommand, reserved); F(ExolegCommand, valve_command);
    F(ExolegCommand, disturbance_estimate_n_per_s2); F(ExolegCommand, log); F(ExolegCommand, message);
    return 0;
}
