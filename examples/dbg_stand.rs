use exoleg::record::{MemoryRecord, RecordSink};
use exoleg::scenario::{Resources, Scenario};
fn main() {
    let args: Vec<String> = std::env::args().skip(2).collect();
    let path = std::env::args().nth(1).unwrap();
    let s = Scenario::load(Some(std::path::Path::new(&path)), &args).unwrap();
    let r = s.resolve(&Resources::new()).unwrap();
    let mut sim = exoleg::sim::Simulation::new(r.model.clone()).unwrap();
    let mut rec = MemoryRecord::default();
    rec.start(&sim.layout()).unwrap();
    for _ in 0..r.model.steps {
        if let Err(e) = sim.step(&mut rec) {
            println!("{e}");
            break;
        }
    }
    let n = rec.rows.len();
    for row in rec.rows.iter().skip(n.saturating_sub(400)).step_by(20) {
        let c = row.contact.unwrap();
        println!(
            "{:.4} Fd {:.1} F {:.1} x2 {:.0} D {:.3e} u {:.4} knee {:.3} grf {:.1} pen {:.5} vp {:.5}",
            row.t_s,
            row.ref_force_n,
            row.load_force_n,
            row.force_rate_n_per_s,
            row.disturbance_estimate_n_per_s2,
            row.valve_command,
            row.leg.unwrap().knee_angle_deg,
            c.ground_reaction_vertical_n,
            c.contact_penetration_m,
            row.piston_velocity_m_s
        );
    }
}
// (rows printed above)
