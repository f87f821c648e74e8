//! Independent reference model for the tests: reads the URDF numbers with roxmltree (not the
//! library's loader), rebuilds the knee + cylinder loop with the law of cosines, and integrates
//! the Lagrange equation of the closed chain reduced to the knee angle with RK4.
//!
//! Assumptions checked here (they hold for both test URDFs): thigh root; `knee` thigh->shank
//! about +-y; `ankle` fixed shank->foot; `barrel_pivot` thigh->barrel about +-y; `rod_slide`
//! prismatic barrel->rod whose origin lies on its axis; closure anchor at the rod frame origin.
#![allow(dead_code)]

use std::collections::HashMap;

pub const G: f64 = 9.81;

#[derive(Clone, Copy, Debug)]
pub struct Body {
    pub m: f64,
    pub cx: f64,
    pub cz: f64,
    pub iyy: f64,
}

#[derive(Clone, Copy, Debug)]
pub struct Jnt {
    pub x: f64,
    pub z: f64,
    pub pitch: f64,
    pub axis: [f64; 3],
}

/// Planar pose (x, z, angle about +y), p_parent = R(a) p + t with R(a)(x,z) = (x c + z s, -x s + z c).
#[derive(Clone, Copy, Debug)]
pub struct P {
    pub x: f64,
    pub z: f64,
    pub a: f64,
}

pub fn rot(x: f64, z: f64, a: f64) -> (f64, f64) {
    let (s, c) = a.sin_cos();
    (x * c + z * s, -x * s + z * c)
}

impl P {
    pub fn apply(&self, x: f64, z: f64) -> (f64, f64) {
        let (rx, rz) = rot(x, z, self.a);
        (self.x + rx, self.z + rz)
    }
    pub fn mul(&self, o: &P) -> P {
        let (x, z) = self.apply(o.x, o.z);
        P { x, z, a: self.a + o.a }
    }
}

pub struct RefModel {
    pub bodies: HashMap<String, Body>,
    pub joints: HashMap<String, Jnt>,
    pub p2: (f64, f64),
}

fn v3(s: &str) -> [f64; 3] {
    let v: Vec<f64> = s.split_whitespace().map(|t| t.parse().unwrap()).collect();
    [v[0], v[1], v[2]]
}

impl RefModel {
    pub fn from_file(path: &str) -> Self {
        let text = std::fs::read_to_string(path).unwrap();
        let doc = roxmltree::Document::parse(&text).unwrap();
        let mut bodies = HashMap::new();
        let mut joints = HashMap::new();
        let mut p2 = (0.0, 0.0);
        for n in doc.root_element().children().filter(|n| n.is_element()) {
            match n.tag_name().name() {
                "link" => {
                    let inertial = n.children().find(|c| c.has_tag_name("inertial")).unwrap();
                    let o = inertial.children().find(|c| c.has_tag_name("origin")).unwrap();
                    let xyz = v3(o.attribute("xyz").unwrap());
                    assert_eq!(o.attribute("rpy").map(v3).unwrap_or([0.0; 3]), [0.0; 3]);
                    let m: f64 = inertial
                        .children()
                        .find(|c| c.has_tag_name("mass"))
                        .unwrap()
                        .attribute("value")
                        .unwrap()
                        .parse()
                        .unwrap();
                    let iyy: f64 = inertial
                        .children()
                        .find(|c| c.has_tag_name("inertia"))
                        .unwrap()
                        .attribute("iyy")
                        .unwrap()
                        .parse()
                        .unwrap();
                    bodies.insert(n.attribute("name").unwrap().to_string(), Body { m, cx: xyz[0], cz: xyz[2], iyy });
                }
                "joint" => {
                    let o = n.children().find(|c| c.has_tag_name("origin")).unwrap();
                    let xyz = v3(o.attribute("xyz").unwrap());
                    let rpy = o.attribute("rpy").map(v3).unwrap_or([0.0; 3]);
                    let axis = n
                        .children()
                        .find(|c| c.has_tag_name("axis"))
                        .map(|a| v3(a.attribute("xyz").unwrap()))
                        .unwrap_or([1.0, 0.0, 0.0]);
                    joints.insert(
                        n.attribute("name").unwrap().to_string(),
                        Jnt { x: xyz[0], z: xyz[2], pitch: rpy[1], axis },
                    );
                }
                "loop_closure" => {
                    let l1 = n.children().find(|c| c.has_tag_name("link1")).unwrap();
                    let l2 = n.children().find(|c| c.has_tag_name("link2")).unwrap();
                    assert_eq!(l1.attribute("name"), Some("rod"));
                    assert_eq!(v3(l1.attribute("xyz").unwrap()), [0.0; 3]);
                    assert_eq!(l2.attribute("name"), Some("shank"));
                    let x = v3(l2.attribute("xyz").unwrap());
                    p2 = (x[0], x[2]);
                }
                _ => {}
            }
        }
        let r = &joints["rod_slide"];
        // rod_slide origin must lie on its axis (through the barrel pivot) for this reference.
        let cross = r.x * r.axis[2] - r.z * r.axis[0];
        assert!(cross.abs() < 1e-12 && r.pitch == 0.0);
        RefModel { bodies, joints, p2 }
    }

    fn j(&self, n: &str) -> &Jnt {
        &self.joints[n]
    }

    /// Law of cosines: pivot P, knee K, rod end R(theta) = K + R_y(s_k theta) p2.
    pub fn rod_end(&self, th: f64) -> (f64, f64) {
        let k = self.j("knee");
        let (rx, rz) = rot(self.p2.0, self.p2.1, k.axis[1] * th);
        (k.x + rx, k.z + rz)
    }

    pub fn length(&self, th: f64) -> f64 {
        let b = self.j("barrel_pivot");
        let k = self.j("knee");
        let a = ((b.x - k.x).powi(2) + (b.z - k.z).powi(2)).sqrt();
        let c = (self.p2.0.powi(2) + self.p2.1.powi(2)).sqrt();
        // angle at the knee between (pivot - knee) and (rod end - knee)
        let (rx, rz) = self.rod_end(th);
        let ang1 = (b.x - k.x).atan2(b.z - k.z);
        let ang2 = (rx - k.x).atan2(rz - k.z);
        let gamma = ang2 - ang1;
        (a * a + c * c - 2.0 * a * c * gamma.cos()).sqrt()
    }

    pub fn moment_arm(&self, th: f64) -> f64 {
        let h = 1e-6;
        (self.length(th + h) - self.length(th - h)) / (2.0 * h)
    }

    /// World poses of (shank, foot, barrel, rod) at a knee angle.
    pub fn poses(&self, th: f64) -> Vec<(&'static str, P)> {
        let k = self.j("knee");
        let an = self.j("ankle");
        let b = self.j("barrel_pivot");
        let r = self.j("rod_slide");
        let shank = P { x: k.x, z: k.z, a: k.axis[1] * th };
        let foot = shank.mul(&P { x: an.x, z: an.z, a: an.pitch });
        let (ex, ez) = self.rod_end(th);
        let (dx, dz) = (ex - b.x, ez - b.z);
        let len = (dx * dx + dz * dz).sqrt();
        // barrel frame angle: rotates the rod axis direction (in barrel frame) onto the pivot->rod end line
        let beta = dx.atan2(dz) - r.axis[0].atan2(r.axis[2]);
        let barrel = P { x: b.x, z: b.z, a: beta };
        let o_along = r.x * r.axis[0] + r.z * r.axis[2];
        let s = len - o_along;
        let rod = barrel.mul(&P { x: r.x + s * r.axis[0], z: r.z + s * r.axis[2], a: 0.0 });
        vec![("shank", shank), ("foot", foot), ("barrel", barrel), ("rod", rod)]
    }

    pub fn potential(&self, th: f64) -> f64 {
        let mut v = 0.0;
        let t = &self.bodies["thigh"];
        v += t.m * G * t.cz;
        for (n, p) in self.poses(th) {
            let b = &self.bodies[n];
            v += b.m * G * p.apply(b.cx, b.cz).1;
        }
        v
    }

    pub fn dv(&self, th: f64) -> f64 {
        let h = 1e-6;
        (self.potential(th + h) - self.potential(th - h)) / (2.0 * h)
    }

    /// Generalized inertia of the closed chain about the knee coordinate.
    pub fn mass(&self, th: f64) -> f64 {
        let h = 1e-6;
        let pp = self.poses(th + h);
        let pm = self.poses(th - h);
        let mut m = 0.0;
        for i in 0..pp.len() {
            let b = &self.bodies[pp[i].0];
            let (xp, zp) = pp[i].1.apply(b.cx, b.cz);
            let (xm, zm) = pm[i].1.apply(b.cx, b.cz);
            let vx = (xp - xm) / (2.0 * h);
            let vz = (zp - zm) / (2.0 * h);
            // wrap: the barrel pitch comes from atan2 and jumps by 2 pi near full extension.
            let w = wrap(pp[i].1.a - pm[i].1.a) / (2.0 * h);
            m += b.m * (vx * vx + vz * vz) + b.iyy * w * w;
        }
        m
    }

    pub fn dmass(&self, th: f64) -> f64 {
        let h = 1e-4;
        (self.mass(th + h) - self.mass(th - h)) / (2.0 * h)
    }

    /// Lagrange: M qdd + 1/2 M' qd^2 + V' = F dL/dq.
    pub fn accel(&self, th: f64, w: f64, force: f64) -> f64 {
        (force * self.moment_arm(th) - 0.5 * self.dmass(th) * w * w - self.dv(th)) / self.mass(th)
    }

    pub fn holding_force(&self, th: f64) -> f64 {
        self.dv(th) / self.moment_arm(th)
    }

    /// RK4 of the passive reduced model; returns samples (t, theta) every `dt`.
    pub fn simulate(&self, th0: f64, dt: f64, t_end: f64) -> Vec<(f64, f64)> {
        let mut out = vec![(0.0, th0)];
        let (mut q, mut w) = (th0, 0.0);
        let n = (t_end / dt).round() as usize;
        for i in 1..=n {
            let k1q = w;
            let k1w = self.accel(q, w, 0.0);
            let k2q = w + 0.5 * dt * k1w;
            let k2w = self.accel(q + 0.5 * dt * k1q, k2q, 0.0);
            let k3q = w + 0.5 * dt * k2w;
            let k3w = self.accel(q + 0.5 * dt * k2q, k3q, 0.0);
            let k4q = w + dt * k3w;
            let k4w = self.accel(q + dt * k3q, k4q, 0.0);
            q += dt / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q);
            w += dt / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w);
            out.push((i as f64 * dt, q));
        }
        out
    }
}

/// Times of the interior local maxima of a sampled signal (parabolic interpolation).
pub fn maxima(samples: &[(f64, f64)]) -> Vec<f64> {
    let mut t = Vec::new();
    for i in 1..samples.len() - 1 {
        let (y0, y1, y2) = (samples[i - 1].1, samples[i].1, samples[i + 1].1);
        if y1 > y0 && y1 >= y2 {
            let h = samples[i + 1].0 - samples[i].0;
            let denom = y0 - 2.0 * y1 + y2;
            let off = if denom.abs() > 0.0 { 0.5 * (y0 - y2) / denom } else { 0.0 };
            t.push(samples[i].0 + off * h);
        }
    }
    t
}

/// Mean period from the maxima (first to last).
pub fn mean_period(samples: &[(f64, f64)]) -> (f64, usize) {
    let m = maxima(samples);
    assert!(m.len() >= 2, "need at least two maxima, got {m:?}");
    ((m[m.len() - 1] - m[0]) / (m.len() - 1) as f64, m.len())
}

pub fn manifest(p: &str) -> String {
    format!("{}/{}", env!("CARGO_MANIFEST_DIR"), p)
}

// ---- Moving hip (thigh hinged at the world origin) ----------------------------------------
//
// Hip flexion `hip` (positive = thigh forward, knee to +x) rotates the whole planar leg by
// `-hip` about +y (P's rotation convention moves a point below the origin to -x for a positive
// angle). The knee/hip generalized forces are computed by the principle of virtual power
// (d'Alembert), not from a Lagrangian mass matrix:
//     Q_j = sum_i m_i (a_i + g z_hat) . dc_i/dq_j + I_i alpha_dd_i dalpha_i/dq_j,
// with the world CoM accelerations a_i and pitch accelerations alpha_dd_i obtained by a second
// difference in time along q(t) = q + qd t + qdd t^2 / 2.

/// Angle difference wrapped to (-pi, pi] (pitches come from atan2 and jump by 2 pi when a
/// body, e.g. the barrel hanging along -z, crosses the branch cut).
pub fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    a - t * (a / t).round()
}

/// Hip motion sample: (angle rad, rate rad/s, acceleration rad/s^2).
pub type Hip3 = (f64, f64, f64);

/// (name, com x, com z, pitch) of every body, see [`RefModel::world_bodies`].
pub type WorldBodies = Vec<(&'static str, f64, f64, f64)>;

impl RefModel {
    /// World (com x, com z, pitch) of thigh, shank, foot, barrel, rod for (hip, knee) angles.
    pub fn world_bodies(&self, hip: f64, th: f64) -> WorldBodies {
        let h = P { x: 0.0, z: 0.0, a: -hip };
        let mut all = vec![("thigh", P { x: 0.0, z: 0.0, a: 0.0 })];
        all.extend(self.poses(th));
        all.into_iter()
            .map(|(n, p)| {
                let w = h.mul(&p);
                let b = &self.bodies[n];
                let (x, z) = w.apply(b.cx, b.cz);
                (n, x, z, w.a)
            })
            .collect()
    }

    /// Generalized forces (hip, knee), N m, needed for the motion `hip`, `knee` =
    /// (angle, rate, acceleration), by virtual power.
    pub fn inverse_dynamics2(&self, hip: Hip3, knee: Hip3) -> (f64, f64) {
        let ht = 1e-4;
        let at = |t: f64| {
            self.world_bodies(hip.0 + hip.1 * t + 0.5 * hip.2 * t * t, knee.0 + knee.1 * t + 0.5 * knee.2 * t * t)
        };
        let (bm, b0, bp) = (at(-ht), at(0.0), at(ht));
        let d = 1e-6;
        let jh = (self.world_bodies(hip.0 + d, knee.0), self.world_bodies(hip.0 - d, knee.0));
        let jk = (self.world_bodies(hip.0, knee.0 + d), self.world_bodies(hip.0, knee.0 - d));
        let (mut qh, mut qk) = (0.0, 0.0);
        for i in 0..b0.len() {
            let b = &self.bodies[b0[i].0];
            let ax = (bp[i].1 - 2.0 * b0[i].1 + bm[i].1) / (ht * ht);
            let az = (bp[i].2 - 2.0 * b0[i].2 + bm[i].2) / (ht * ht) + G;
            let aa = (wrap(bp[i].3 - b0[i].3) - wrap(b0[i].3 - bm[i].3)) / (ht * ht);
            let proj = |j: &(WorldBodies, WorldBodies)| {
                let dx = (j.0[i].1 - j.1[i].1) / (2.0 * d);
                let dz = (j.0[i].2 - j.1[i].2) / (2.0 * d);
                let da = wrap(j.0[i].3 - j.1[i].3) / (2.0 * d);
                b.m * (ax * dx + az * dz) + b.iyy * aa * da
            };
            qh += proj(&jh);
            qk += proj(&jk);
        }
        (qh, qk)
    }

    /// Knee acceleration for a generalized knee force `tau` with a prescribed hip (the knee row
    /// is affine in the knee acceleration).
    pub fn accel_with_hip(&self, hip: Hip3, th: f64, w: f64, tau: f64) -> f64 {
        let q0 = self.inverse_dynamics2(hip, (th, w, 0.0)).1;
        let q1 = self.inverse_dynamics2(hip, (th, w, 1.0)).1;
        (tau - q0) / (q1 - q0)
    }

    /// RK4 of the passive knee (tau = 0) with a prescribed hip `hip(t)`; samples (t, theta).
    pub fn simulate_with_hip(
        &self,
        th0: f64,
        w0: f64,
        hip: impl Fn(f64) -> Hip3,
        dt: f64,
        t_end: f64,
    ) -> Vec<(f64, f64)> {
        let mut out = vec![(0.0, th0)];
        let (mut q, mut w) = (th0, w0);
        let n = (t_end / dt).round() as usize;
        for i in 0..n {
            let t = i as f64 * dt;
            let (h0, hm, h1) = (hip(t), hip(t + 0.5 * dt), hip(t + dt));
            let k1q = w;
            let k1w = self.accel_with_hip(h0, q, w, 0.0);
            let k2q = w + 0.5 * dt * k1w;
            let k2w = self.accel_with_hip(hm, q + 0.5 * dt * k1q, k2q, 0.0);
            let k3q = w + 0.5 * dt * k2w;
            let k3w = self.accel_with_hip(hm, q + 0.5 * dt * k2q, k3q, 0.0);
            let k4q = w + dt * k3w;
            let k4w = self.accel_with_hip(h1, q + dt * k3q, k4q, 0.0);
            q += dt / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q);
            w += dt / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w);
            out.push(((i + 1) as f64 * dt, q));
        }
        out
    }
}
