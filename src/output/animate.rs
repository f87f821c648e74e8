//! `leg_motion.gif` (`exoleg run --animate`): the sagittal leg in motion. Thigh, shank and
//! foot as bones, the cylinder coloured by its force (blue pulling, red pushing, scaled to the
//! run's largest force), the cuff force as an arrow, the ground and its reaction when contact
//! is on, and the time and the force error written on each frame.
//!
//! Frames are taken from the recorded rows in real time (one every [`MIN_FRAME_S`], or more
//! sparsely so that a run has at most [`MAX_FRAMES`]), at a whole number of GIF centiseconds,
//! so the GIF plays at the simulation's speed. The same run gives the same bytes.

use crate::error::{Error, Result};
use crate::leg::planar::P2;
use crate::leg::{link_poses_full_at, JointKind, LegSpec};
use crate::record::{Layout, RecordSink, Row};
use plotters::prelude::*;
use std::path::Path;

/// Shortest frame interval (s): 25 frames per second.
pub const MIN_FRAME_S: f64 = 0.04;
/// Most frames in one GIF.
pub const MAX_FRAMES: usize = 500;
const SIZE: (u32, u32) = (480, 480);

/// One frame's state.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Frame {
    t_s: f64,
    hip_rad: f64,
    knee_rad: f64,
    ankle_rad: f64,
    /// Hip height above the ground (m), with contact.
    pelvis_m: Option<f64>,
    cylinder_n: f64,
    cuff_n: f64,
    arm_sign: f64,
    force_error_n: f64,
    grf_n: Option<[f64; 2]>,
}

/// Collects the frames of a run (a [`RecordSink`]).
#[derive(Debug, Clone)]
pub struct Animation {
    interval_s: f64,
    next_s: f64,
    frames: Vec<Frame>,
}

impl Animation {
    /// Frames for a run of `duration_s` (s).
    pub fn new(duration_s: f64) -> Self {
        let raw = (duration_s / MAX_FRAMES as f64).max(MIN_FRAME_S);
        // A whole number of centiseconds, the GIF's unit.
        let interval_s = (raw * 100.0).ceil() / 100.0;
        Self { interval_s, next_s: 0.0, frames: Vec::new() }
    }

    /// Frames taken so far.
    pub fn frame_count(&self) -> usize {
        self.frames.len()
    }

    /// The frame interval (s).
    pub fn interval_s(&self) -> f64 {
        self.interval_s
    }
}

impl RecordSink for Animation {
    fn start(&mut self, _layout: &Layout) -> Result<()> {
        Ok(())
    }

    fn row(&mut self, r: &Row) -> Result<()> {
        let Some(l) = r.leg else { return Ok(()) };
        if r.t_s + 1e-9 < self.next_s || self.frames.len() >= MAX_FRAMES {
            return Ok(());
        }
        self.next_s += self.interval_s;
        let c = r.contact;
        self.frames.push(Frame {
            t_s: r.t_s,
            hip_rad: l.hip_angle_deg.to_radians(),
            knee_rad: l.knee_angle_deg.to_radians(),
            ankle_rad: c.map_or(0.0, |c| c.ankle_angle_deg.to_radians()),
            pelvis_m: c.map(|c| c.pelvis_height_m),
            cylinder_n: r.cylinder_force_n,
            cuff_n: r.interaction_force,
            arm_sign: l.moment_arm_m.signum(),
            force_error_n: r.force_error_n,
            grf_n: c.map(|c| [c.ground_reaction_horizontal_n, c.ground_reaction_vertical_n]),
        });
        Ok(())
    }
}

/// What the picture needs besides the frames.
#[derive(Debug, Clone, Copy)]
pub struct Scene<'a> {
    /// The leg.
    pub model: &'a LegSpec,
    /// The cuff point in the shank frame (m), when the cuff force acts.
    pub cuff_m: Option<[f64; 3]>,
    /// Ground height in the hip frame (m) without the carriage (with it, the pelvis height
    /// places the ground).
    pub ground_z_m: Option<f64>,
}

/// Write the frames as a GIF to `path`.
pub fn write_gif(path: &Path, anim: &Animation, scene: &Scene) -> Result<()> {
    super::plot::ensure_font();
    let werr = |e: String| Error::Write { path: path.to_path_buf(), message: format!("animation: {e}") };
    let delay_ms = (anim.interval_s * 1000.0).round() as u32;
    let root = BitMapBackend::gif(path, SIZE, delay_ms).map_err(|e| werr(e.to_string()))?.into_drawing_area();
    let f_max = anim.frames.iter().map(|f| f.cylinder_n.abs()).fold(1.0, f64::max);
    for f in &anim.frames {
        root.fill(&WHITE).map_err(|e| werr(e.to_string()))?;
        draw_frame(&root, f, scene, f_max).map_err(werr)?;
        root.present().map_err(|e| werr(e.to_string()))?;
    }
    Ok(())
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

/// World (hip frame, m) to pixels: x in [-0.6, 0.6], z in [-1.05, 0.15].
fn px(p: P2) -> (i32, i32) {
    let s = SIZE.0 as f64 / 1.2;
    (((p.x + 0.6) * s).round() as i32, ((0.15 - p.z) * s).round() as i32)
}

/// Blue (pulling) to red (pushing), by `f / f_max`.
fn force_colour(f: f64, f_max: f64) -> RGBColor {
    let u = (f / f_max).clamp(-1.0, 1.0);
    let a = (u.abs() * 255.0) as u8;
    if u >= 0.0 {
        RGBColor(a.max(60), 40, 40)
    } else {
        RGBColor(40, 40, a.max(60))
    }
}

fn arrow(root: &Area, from: P2, d: P2, colour: RGBColor) -> std::result::Result<(), String> {
    let to = from.plus(d);
    let style = ShapeStyle::from(colour).stroke_width(3);
    root.draw(&PathElement::new(vec![px(from), px(to)], style)).map_err(|e| e.to_string())?;
    let n = d.norm();
    if n > 1e-6 {
        let (u, v) = (d.scale(0.04 / n), P2::new(-d.z, d.x).scale(0.02 / n));
        let head = vec![px(to), px(to.minus(u).plus(v)), px(to.minus(u).minus(v))];
        root.draw(&Polygon::new(head, colour.filled())).map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn draw_frame(root: &Area, f: &Frame, scene: &Scene, f_max: f64) -> std::result::Result<(), String> {
    let m = scene.model;
    let e = |e: DrawingAreaErrorKind<_>| e.to_string();
    let poses = link_poses_full_at(m, f.hip_rad, f.knee_rad, f.ankle_rad).ok_or("the loop does not close")?;
    let ground_z = f.pelvis_m.map(|h| -h).or(scene.ground_z_m);
    if let Some(z) = ground_z {
        let style = ShapeStyle::from(RGBColor(120, 100, 80)).stroke_width(3);
        root.draw(&PathElement::new(vec![px(P2::new(-0.6, z)), px(P2::new(0.6, z))], style)).map_err(e)?;
    }
    let cyl = [m.barrel_joint().child, m.rod_joint().child];
    let bone = ShapeStyle::from(RGBColor(60, 60, 60)).stroke_width(6);
    for j in m.joints() {
        let moving = matches!(j.kind, JointKind::Revolute | JointKind::Continuous | JointKind::Fixed);
        if moving && !cyl.contains(&j.child) && !cyl.contains(&j.parent) {
            root.draw(&PathElement::new(vec![px(poses[j.parent].t), px(poses[j.child].t)], bone)).map_err(e)?;
        }
    }
    for c in m.collisions() {
        let centre = poses[c.link].apply(P2::new(c.origin_xyz[0], c.origin_xyz[2]));
        root.draw(&PathElement::new(vec![px(poses[c.link].t), px(centre)], bone)).map_err(e)?;
        root.draw(&Circle::new(px(centre), 4, RGBColor(60, 60, 60).filled())).map_err(e)?;
    }
    let lc = m.loop_closure();
    let rod_end = poses[lc.link1].apply(P2::new(lc.anchor1_m[0], lc.anchor1_m[2]));
    let pivot = poses[m.barrel_joint().child].t;
    let cyl_style = ShapeStyle::from(force_colour(f.cylinder_n, f_max)).stroke_width(8);
    root.draw(&PathElement::new(vec![px(pivot), px(rod_end)], cyl_style)).map_err(e)?;
    for p in [P2::default(), poses[m.knee_joint().child].t, pivot, rod_end] {
        root.draw(&Circle::new(px(p), 5, BLACK.filled())).map_err(e)?;
    }
    if let Some(cp) = scene.cuff_m {
        let shank = m.knee_joint().child;
        let p = poses[shank].apply(P2::new(cp[0], cp[2]));
        let r = p.minus(poses[shank].t);
        let dir = P2::new(r.z, -r.x).scale(1.0 / r.norm().max(1e-9));
        arrow(root, p, dir.scale(-f.arm_sign * f.cuff_n * 0.002), RGBColor(0, 150, 0))?;
    }
    if let (Some(g), Some(z)) = (f.grf_n, ground_z) {
        if g[1] > 1.0 {
            let low =
                crate::leg::foot_points_at(m, f.hip_rad, f.knee_rad, f.ankle_rad).map_or(P2::new(0.0, z), |p| p.lowest);
            arrow(root, P2::new(low.x, z), P2::new(g[0], g[1]).scale(0.0004), RGBColor(200, 120, 0))?;
        }
    }
    let text = format!("t = {:.2} s   F_L - F_d = {:+.2} N", f.t_s, f.force_error_n);
    root.draw(&Text::new(text, (10, 10), ("sans-serif", 18).into_font().color(&BLACK))).map_err(e)?;
    Ok(())
}
