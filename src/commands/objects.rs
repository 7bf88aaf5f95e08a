//! `slidetrack objects`: the built-in objects of the simulated rig.

use anyhow::Result;
use slidetrack_experiment::trial_inputs::builtin_objects;

pub fn run() -> Result<()> {
    println!(
        "{:<9} {:>8} {:>6} {:>6} {:>16} {:>8}  description",
        "object", "mass kg", "mu_s", "mu_k", "grasp counts", "period"
    );
    for o in builtin_objects()? {
        let e = &o.experiment;
        println!(
            "{:<9} {:>8.3} {:>6.2} {:>6.2} {:>7.0}..{:<7.0} {:>6.1} s  {}",
            o.name,
            o.mass_kg,
            o.friction.mu_static,
            o.friction.mu_kinetic,
            e.grasp_min_counts,
            e.grasp_max_counts,
            e.period_s,
            o.description
        );
    }
    println!("\nA path to an object .toml (same fields as sim/objects/*.toml) works wherever a name does.");
    Ok(())
}
