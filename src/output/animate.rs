//! `leg_motion.gif` (`exoleg run --animate`): the sagittal leg in motion. Thigh, shank and
//! foot as bones, the cylinder coloured by its force (blue pulling, red pushing, scaled to the
//! run's largest force), the cuff force as an arrow, the ground and its reaction when contact
//! is on, and the time and the force error written on each frame.
//!
//! Frames are taken from the recorded rows in real time: every k-th row, k chosen so the frame
//! interval is at least [`MIN_FRAME_S`], at most [`MAX_FRAMES`] frames cover the run, and the
//! interval is a whole number of GIF centiseconds to within 1 % (so the GIF plays at the
//! simulation's speed, also for steps longer than a frame). A GIF delay is at most 655.35 s:
//! runs over [`MAX_FRAMES`] times that (about 3.8 days) play faster than real time. The same
//! run gives the same bytes.

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

/// Longest GIF frame delay (centiseconds; the format's 16 bits).
pub const MAX_DELAY_CS: u16 = u16::MAX;

/// The frames of a run: every `every` rows, shown `delay_cs` centiseconds each.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FramePlan {
    /// A frame every this many rows (steps).
    pub every: usize,
    /// Frames in the GIF.
    pub frames: usize,
    /// Each frame's delay (cs).
    pub delay_cs: u16,
}

impl FramePlan {
    /// The frames of a run of `steps` steps of `dt_s` (s): the fewest rows per frame that give
    /// at least [`MIN_FRAME_S`] per frame and at most [`MAX_FRAMES`] frames, and then a
    /// frame interval within 1 % of a whole number of centiseconds (the GIF's unit).
    pub fn new(steps: usize, dt_s: f64) -> Self {
        let duration = steps as f64 * dt_s;
        let min_s = (duration / MAX_FRAMES as f64).max(MIN_FRAME_S);
        let k0 = ((min_s / dt_s) * (1.0 - 1e-12)).ceil().max(1.0) as usize;
        let whole = |k: usize| {
            let cs = k as f64 * dt_s * 100.0;
            (cs - cs.round()).abs() <= 0.01 * cs
        };
        let every = (k0..=k0.saturating_mul(4)).find(|&k| whole(k)).unwrap_or(k0);
        let cs = (every as f64 * dt_s * 100.0).round().clamp(1.0, MAX_DELAY_CS as f64);
        let frames = (steps / every + 1).min(MAX_FRAMES);
        Self { every, frames, delay_cs: cs as u16 }
    }
}

/// Collects the frames of a run (a [`RecordSink`]).
#[derive(Debug, Clone)]
pub struct Animation {
    plan: FramePlan,
    row: usize,
    frames: Vec<Frame>,
}

impl Animation {
    /// Frames for a run of `steps` steps of `dt_s` (s).
    pub fn new(steps: usize, dt_s: f64) -> Self {
        Self { plan: FramePlan::new(steps, dt_s), row: 0, frames: Vec::new() }
    }

    /// Frames taken so far.
    pub fn frame_count(&self) -> usize {
        self.frames.len()
    }

    /// The plan of the frames.
    pub fn plan(&self) -> FramePlan {
        self.plan
    }
}

impl RecordSink for Animation {
    fn start(&mut self, _layout: &Layout) -> Result<()> {
        Ok(())
    }

    fn row(&mut self, r: &Row) -> Result<()> {
        let Some(l) = r.leg else { return Ok(()) };
        let row = self.row;
        self.row += 1;
        if !row.is_multiple_of(self.plan.every) || self.frames.len() >= self.plan.frames {
            return Ok(());
        }
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
    // plotters takes milliseconds and stores centiseconds.
    let delay_ms = u32::from(anim.plan.delay_cs) * 10;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Real time for any step: the frame interval is rows x dt, a whole number of centiseconds
    /// (to 1 %), at most 500 frames; the delay never wraps.
    #[test]
    fn frames_play_in_real_time() {
        // 2 s at 1 ms: a frame every 40 ms, 51 frames of 4 cs.
        assert_eq!(FramePlan::new(2000, 1e-3), FramePlan { every: 40, frames: 51, delay_cs: 4 });
        // 60 s: 500 frames 12 cs apart.
        assert_eq!(FramePlan::new(60_000, 1e-3), FramePlan { every: 120, frames: 500, delay_cs: 12 });
        // Steps longer than a frame: every row, each shown for its own step.
        assert_eq!(FramePlan::new(100, 0.05), FramePlan { every: 1, frames: 101, delay_cs: 5 });
        // 45 ms steps: 4.5 cs is no GIF delay; two rows are 9 cs exactly.
        assert_eq!(FramePlan::new(100, 0.045), FramePlan { every: 2, frames: 51, delay_cs: 9 });
        // 0.25 ms steps (the gait scenarios), 5.5 s.
        assert_eq!(FramePlan::new(22_000, 2.5e-4), FramePlan { every: 160, frames: 138, delay_cs: 4 });
        // A week at 1 s steps: 500 frames, the delay capped at 655.35 s (faster than real time).
        let week = FramePlan::new(604_800, 1.0);
        assert_eq!((week.frames, week.delay_cs), (500, MAX_DELAY_CS));
    }
}
