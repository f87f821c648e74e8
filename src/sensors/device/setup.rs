//! The device's sensors from a scenario: each channel's figures from its preset and its keys,
//! the sample rates, and the setup the sensor chain runs.

use super::*;

/// The `device` preset's (or another preset's) default figures of a device channel.
pub fn preset_figures(preset: SensorPreset, c: &DeviceChannel) -> DeviceFigures {
    use device_preset as d;
    let bits = preset.bits().unwrap_or(0);
    let mut f = DeviceFigures {
        enabled: true,
        noise_std: 0.0,
        bias: 0.0,
        bias_step: 0.0,
        scale_error: 0.0,
        bits,
        range: c.default_range,
        threshold: 0.0,
    };
    if preset != SensorPreset::Device {
        return f;
    }
    match c.kind {
        DeviceKind::Hip => f.bits = d::ENCODER_BITS,
        DeviceKind::Accel(_, axis) => {
            (f.bias, f.scale_error, f.bits) = (d::ACCEL_BIAS[axis], d::ACCEL_SCALE[axis], d::IMU_BITS);
        }
        DeviceKind::Gyro(_, axis) => {
            (f.bias, f.scale_error, f.bits) = (d::GYRO_BIAS[axis], d::GYRO_SCALE[axis], d::IMU_BITS);
        }
        DeviceKind::Foot(_) => {
            (f.threshold, f.noise_std, f.range, f.bits) = (d::FOOT.0, d::FOOT.1, d::FOOT.2, d::FOOT.3);
        }
        DeviceKind::Plain if c.unit == "N" => (f.noise_std, f.bits) = d::CUFF,
        DeviceKind::Plain => (f.noise_std, f.bits) = d::PRESSURE,
    }
    f
}

/// What the device's defaults depend on in the leg: the IMUs' mounting points (m, link frame)
/// and the foot sensors' positions along the foot (m, foot frame x), from the URDF.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceDefaults {
    /// Default mounting points of the thigh and shank IMUs (m, link frame).
    pub imu_xyz_m: [[f64; 3]; 2],
    /// Default heel and forefoot sensor positions (m, foot frame x).
    pub foot_x_m: (f64, f64),
}

/// Preset output data rates (Hz) of the `device` preset's IMUs and foot sensors.
const DEVICE_RATES_HZ: [f64; 3] = [1000.0, 1000.0, device_preset::FOOT.4];

impl crate::sensors::SensorParams {
    /// The device sensors' settings (`[sensors.<device sensor>]`) beyond ideal sampling.
    pub(in crate::sensors) fn device_has_effects(&self) -> bool {
        let plain = [&self.hip, &self.thigh_cuff, &self.shank_cuff, &self.pressure_a, &self.pressure_b]
            .into_iter()
            .chain([&self.supply_pressure, &self.load_pressure])
            .any(|c| c.noise_std.unwrap_or(0.0) > 0.0 || c.bits.unwrap_or(0) > 0 || !c.enabled);
        let axes = |a: &ImuAxes| {
            a.noise_density.unwrap_or(0.0) > 0.0
                || a.bias.is_some_and(|b| b != [0.0; 3])
                || a.bias_random_walk.unwrap_or(0.0) > 0.0
                || a.scale_error.is_some_and(|b| b != [0.0; 3])
                || a.bits.unwrap_or(0) > 0
        };
        let imu = |i: &ImuParams| !i.enabled || i.rate_hz.is_some() || axes(&i.accel) || axes(&i.gyro);
        let f = &self.foot;
        plain
            || imu(&self.thigh_imu)
            || imu(&self.shank_imu)
            || !f.enabled
            || f.rate_hz.is_some()
            || f.threshold_n.unwrap_or(0.0) > 0.0
            || f.noise_std.unwrap_or(0.0) > 0.0
            || f.bits.unwrap_or(0) > 0
    }

    /// The settings of a plain device channel (hip, cuffs, pressures) by its key.
    fn plain(&self, key: &str) -> &crate::sensors::ChannelParams {
        match key {
            "hip" => &self.hip,
            "thigh_cuff" => &self.thigh_cuff,
            "shank_cuff" => &self.shank_cuff,
            "pressure_a" => &self.pressure_a,
            "pressure_b" => &self.pressure_b,
            "supply_pressure" => &self.supply_pressure,
            _ => &self.load_pressure,
        }
    }

    /// Samples per update of the thigh IMU, the shank IMU and the foot sensors for a
    /// controller sampled every `period_s`: an explicit rate must divide the sample rate
    /// (errors name the key); a preset's rate applies where it does, else the sample rate.
    fn device_every(&self, period_s: f64) -> Result<[usize; 3], (String, String)> {
        let fs = 1.0 / period_s;
        let rates = [
            ("sensors.thigh_imu.rate_hz", self.thigh_imu.rate_hz),
            ("sensors.shank_imu.rate_hz", self.shank_imu.rate_hz),
            ("sensors.foot.rate_hz", self.foot.rate_hz),
        ];
        let mut every = [1; 3];
        for (i, (key, rate)) in rates.into_iter().enumerate() {
            let ratio = |r: f64| {
                let n = (fs / r).round();
                (n >= 1.0 && (fs / r - n).abs() <= 1e-9 * n).then_some(n as usize)
            };
            every[i] = match rate {
                Some(r) if !(r > 0.0 && r.is_finite()) => {
                    return Err((key.into(), format!("must be > 0 Hz, got {}", r)))
                }
                Some(r) => ratio(r).ok_or_else(|| {
                    (
                        key.to_string(),
                        format!(
                            "{} Hz does not divide the controller's sample rate ({} Hz, controller.sample_period_s): the sensor updates every whole number of samples",
                            r,
                            fs
                        ),
                    )
                })?,
                None if self.preset == SensorPreset::Device => ratio(DEVICE_RATES_HZ[i]).unwrap_or(1),
                None => 1,
            };
        }
        Ok(every)
    }

    /// One device channel's figures: the preset's, then the scenario's explicit values; an
    /// IMU's noise density and bias walk at its rate `rate_hz`.
    fn device_figures(&self, c: &DeviceChannel, rate_hz: f64) -> DeviceFigures {
        use device_preset as d;
        let mut f = preset_figures(self.preset, c);
        let device = self.preset == SensorPreset::Device;
        let imus = [&self.thigh_imu, &self.shank_imu];
        let (imu, axes, axis, nd, brw) = match c.kind {
            DeviceKind::Accel(g, a) => (imus[g], &imus[g].accel, a, d::ACCEL_NOISE_DENSITY, d::ACCEL_BIAS_RW),
            DeviceKind::Gyro(g, a) => (imus[g], &imus[g].gyro, a, d::GYRO_NOISE_DENSITY, d::GYRO_BIAS_RW),
            DeviceKind::Foot(_) => {
                let p = &self.foot;
                f.enabled = p.enabled;
                f.threshold = p.threshold_n.unwrap_or(f.threshold);
                f.noise_std = p.noise_std.unwrap_or(f.noise_std);
                f.range = p.range.unwrap_or(f.range);
                f.bits = p.bits.unwrap_or(f.bits);
                return f;
            }
            DeviceKind::Hip | DeviceKind::Plain => {
                let p = self.plain(c.key);
                f.enabled = p.enabled;
                f.noise_std = p.noise_std.unwrap_or(f.noise_std);
                f.range = p.range.unwrap_or(f.range);
                f.bits = p.bits.unwrap_or(f.bits);
                return f;
            }
        };
        let preset = |x: f64| if device { x } else { 0.0 };
        f.enabled = imu.enabled;
        f.noise_std = axes.noise_density.unwrap_or(preset(nd)) * rate_hz.sqrt();
        f.bias = axes.bias.map_or(f.bias, |b| b[axis]);
        f.bias_step = axes.bias_random_walk.unwrap_or(preset(brw)) / rate_hz.sqrt();
        f.scale_error = axes.scale_error.map_or(f.scale_error, |s| s[axis]);
        f.range = axes.range.unwrap_or(f.range);
        f.bits = axes.bits.unwrap_or(f.bits);
        f
    }

    /// The device's chain settings for a controller sampled every `period_s` (s) on a leg
    /// with `defaults`; errors name the key.
    pub fn device_setup(&self, period_s: f64, defaults: &DeviceDefaults) -> Result<DeviceSetup, (String, String)> {
        let every = self.device_every(period_s)?;
        let rate = |g: usize| 1.0 / (every[g] as f64 * period_s);
        let figures = std::array::from_fn(|i| {
            let c = &DEVICE_CHANNELS[i];
            let g = match c.kind {
                DeviceKind::Accel(g, _) | DeviceKind::Gyro(g, _) => g,
                _ => 2,
            };
            self.device_figures(c, rate(g))
        });
        let mount = |p: &ImuParams, i: usize| {
            let xyz = p.xyz_m.unwrap_or(defaults.imu_xyz_m[i]);
            ([xyz[0], xyz[2]], rpy_matrix(p.rpy_rad))
        };
        let foot_x_m =
            (self.foot.heel_x_m.unwrap_or(defaults.foot_x_m.0), self.foot.forefoot_x_m.unwrap_or(defaults.foot_x_m.1));
        if foot_x_m.1 <= foot_x_m.0 {
            return Err((
                "sensors.foot.forefoot_x_m".into(),
                format!("must lie ahead of the heel sensor ({} m), got {} m", foot_x_m.0, foot_x_m.1),
            ));
        }
        Ok(DeviceSetup { figures, every, imu_mount: [mount(&self.thigh_imu, 0), mount(&self.shank_imu, 1)], foot_x_m })
    }
}
