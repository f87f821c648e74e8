//! The device's sensor chain as it runs: each channel's truth (the IMUs' specific force and
//! rate in their frames), its noise, bias, drift and A/D, at its own rate.

use super::*;

impl DeviceSensors {
    /// The chain of `setup` for a controller sampled every `period_s` (s) with the run's
    /// `delay` (samples) and derivative filter `alpha`, noise seeded from `seed`.
    pub fn new(setup: DeviceSetup, period_s: f64, delay: usize, alpha: f64, seed: u64) -> Self {
        let adc = setup.figures.map(Adc::new);
        let rngs = (0..DEVICE_CHANNELS.len())
            .map(|i| ChaCha8Rng::seed_from_u64(seed ^ 0xD3C1_5E45_0000_0000 ^ (i as u64 + 1).wrapping_mul(0x9E37_79B9)))
            .collect();
        Self {
            setup,
            adc,
            rngs,
            walk: [0.0; 21],
            held: [f64::NAN; 21],
            held_counts: [None; 21],
            clipped: [0; 21],
            imu: [ImuTrack::default(); 2],
            samples: 0,
            period_s,
            alpha,
            delay,
            line: VecDeque::with_capacity(delay + 1),
            d_hip: Differentiator::default(),
        }
    }

    /// Readings that clipped at full scale so far, by reading name.
    pub fn clipped(&self) -> Vec<(&'static str, usize)> {
        DEVICE_CHANNELS.iter().map(|c| c.reading).zip(self.clipped).filter(|(_, n)| *n > 0).collect()
    }

    /// The true values of the channels at this sample (before noise), updating the IMUs'
    /// velocity tracks when they sample. `update[g]`: group g (thigh IMU, shank IMU, foot)
    /// samples now.
    pub(super) fn truth_values(&mut self, t: &DeviceTruth, update: [bool; 3]) -> [f64; 21] {
        let mut x = [f64::NAN; 21];
        if let Some(leg) = &t.leg {
            x[0] = leg.hip.0;
            for (i, seg) in [leg.thigh, leg.shank].iter().enumerate() {
                if update[i] {
                    let (acc, gyro) = self.imu_truth(i, seg);
                    x[1 + 6 * i..4 + 6 * i].copy_from_slice(&acc);
                    x[4 + 6 * i..7 + 6 * i].copy_from_slice(&gyro);
                }
            }
        }
        if let Some(f) = &t.foot {
            let (h, fore) = f.split(self.setup.foot_x_m.0, self.setup.foot_x_m.1);
            (x[13], x[14]) = (h, fore);
        }
        x[15..21].copy_from_slice(&[
            t.thigh_cuff_force_n,
            t.shank_cuff_force_n,
            t.pressure_a_pa,
            t.pressure_b_pa,
            t.supply_pressure_pa,
            t.load_pressure_pa,
        ]);
        x
    }

    /// IMU `i`'s true specific force (m/s^2) and angular velocity (rad/s) in its frame, from
    /// its segment's state; the mounting point's velocity is kept for the next sample.
    pub(super) fn imu_truth(&mut self, i: usize, seg: &SegmentState) -> ([f64; 3], [f64; 3]) {
        let (u, r_ls) = self.setup.imu_mount[i];
        let (_, v) = seg.point(u);
        let dt = self.setup.every[i] as f64 * self.period_s;
        let a = match self.imu[i].last_velocity {
            Some((v0, _)) => [(v[0] - v0[0]) / dt, (v[1] - v0[1]) / dt],
            None => [0.0, 0.0],
        };
        self.imu[i].last_velocity = Some((v, seg.omega_rad_s));
        let f_w = [a[0], 0.0, a[1] + GRAVITY_M_S2];
        let w_w = [0.0, seg.omega_rad_s, 0.0];
        // Sensor frame: R_WS = R_y(link) R_LS; a world vector in the sensor frame is
        // R_LS^T R_y^T v.
        let (c, s) = seg.cos_sin;
        let to_link = |v: [f64; 3]| [v[0] * c - v[2] * s, v[1], v[0] * s + v[2] * c];
        let to_sensor =
            |v: [f64; 3]| std::array::from_fn(|k| r_ls[0][k] * v[0] + r_ls[1][k] * v[1] + r_ls[2][k] * v[2]);
        (to_sensor(to_link(f_w)), to_sensor(to_link(w_w)))
    }

    /// One channel's reading from its true value `x` (its sensor sampled now).
    pub(super) fn read(&mut self, i: usize, x: f64) -> (f64, Option<i64>) {
        let adc = self.adc[i];
        let fig = &adc.fig;
        if !fig.enabled || x.is_nan() {
            return (f64::NAN, None);
        }
        let rng = &mut self.rngs[i];
        if fig.bias_step > 0.0 {
            let z: f64 = StandardNormal.sample(rng);
            self.walk[i] += fig.bias_step * z;
        }
        let n = if fig.noise_std > 0.0 {
            let z: f64 = StandardNormal.sample(rng);
            fig.noise_std * z
        } else {
            0.0
        };
        let v = (1.0 + fig.scale_error) * x + fig.bias + self.walk[i] + n;
        self.clipped[i] += usize::from(v.abs() > fig.range);
        let (y, counts) = adc.convert(v);
        if matches!(DEVICE_CHANNELS[i].kind, DeviceKind::Foot(_)) && y < fig.threshold.max(f64::MIN_POSITIVE) {
            return (0.0, adc.convert(0.0).1);
        }
        (y, counts)
    }

    /// Take one sample of the device at a controller sample instant: the readings and their
    /// raw A/D counts.
    pub fn sample(&mut self, truth: &DeviceTruth) -> (DeviceReadings, DeviceCounts) {
        self.sample_with(truth, None)
    }

    /// [`Self::sample`] with the run's sensor faults (see `SampledSensors::sample_with`).
    pub fn sample_with(
        &mut self,
        truth: &DeviceTruth,
        faults: Option<crate::sensors::FaultHook>,
    ) -> (DeviceReadings, DeviceCounts) {
        let k = self.samples;
        self.samples += 1;
        let update = self.setup.every.map(|e| k.is_multiple_of(e));
        let x = self.truth_values(truth, update);
        for (i, c) in DEVICE_CHANNELS.iter().enumerate() {
            let group = match c.kind {
                DeviceKind::Accel(g, _) | DeviceKind::Gyro(g, _) => Some(g),
                DeviceKind::Foot(_) => Some(2),
                DeviceKind::Hip | DeviceKind::Plain => None,
            };
            if group.is_none_or(|g| update[g]) {
                (self.held[i], self.held_counts[i]) = self.read(i, x[i]);
            }
        }
        let (mut r, mut counts) = if self.delay == 0 {
            (self.held, DeviceCounts(self.held_counts))
        } else {
            self.line.push_back((self.held, DeviceCounts(self.held_counts)));
            if self.line.len() > self.delay {
                self.line.pop_front().unwrap_or_default()
            } else {
                self.line[0]
            }
        };
        if let Some((f, t, active)) = faults {
            f.apply(t, crate::sensors::CHANNELS.len(), &mut r, &mut counts.0, active);
        }
        let hip_rate = match r[0].is_nan() {
            true => f64::NAN,
            false => {
                let initial = truth.leg.map_or(0.0, |l| l.hip.1);
                self.d_hip.update(r[0], self.period_s, self.alpha, initial)
            }
        };
        let foot_contact = match (r[13].is_nan(), r[14].is_nan()) {
            (true, true) => f64::NAN,
            _ => f64::from(u8::from(r[13] > 0.0 || r[14] > 0.0)),
        };
        let mut v = [0.0; DEVICE_READINGS];
        v[0] = r[0];
        v[1] = hip_rate;
        v[2..16].copy_from_slice(&r[1..15]);
        v[16] = foot_contact;
        v[17..23].copy_from_slice(&r[15..21]);
        (DeviceReadings::from_values(&v), counts)
    }
}
