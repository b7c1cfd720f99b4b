//! Loads a URDF through the library API, perturbs one parameter by name, and prints how the mass
//! matrix and the gravity torques change.
//!
//! `cargo run --release --example dynamics_at_a_state -- robots/ur5/ur5.urdf`

use ribbon::dynamics::{crba, nonlinear_effects, Data};
use ribbon::environment::Environment;
use ribbon::model::{LoadOptions, Model};
use ribbon::params;
use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let path = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("robots/ur5/ur5.urdf"));
    match run(&path) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::from(error.exit_code())
        }
    }
}

fn run(path: &std::path::Path) -> Result<(), ribbon::Error> {
    let mut model = Model::from_urdf_file(path, LoadOptions::default())?;
    let mut data = Data::new(&model);
    let q: Vec<f64> = (0..model.nq).map(|i| 0.2 * i as f64 - 0.4).collect();
    let v = vec![0.0; model.nv];
    // Standard gravity and no contacts: the environment a scene without `gravity` gives.
    let mut environment = Environment::default();
    let gravity = environment.gravity;

    let nominal_mass = crba(&model, &mut data, &q).clone();
    let nominal_gravity = nonlinear_effects(&model, &gravity, &mut data, &q, &v).to_vec();

    // The heaviest link gets 5 % more mass, addressed by its parameter path.
    let heaviest = model
        .description
        .links
        .iter()
        .max_by(|a, b| a.inertial.mass.total_cmp(&b.inertial.mass))
        .map(|l| l.name.clone())
        .unwrap_or_default();
    let target = params::resolve(&model, &environment, &format!("link.{heaviest}.mass"))?;
    let nominal = params::get(&model, &environment, target);
    params::apply(&mut model, &mut environment, &[target], &[nominal * 1.05]);

    let perturbed_mass = crba(&model, &mut data, &q).clone();
    let perturbed_gravity = nonlinear_effects(&model, &gravity, &mut data, &q, &v).to_vec();
    println!("robot '{}': {} coordinates", model.name(), model.nv);
    println!(
        "link.{heaviest}.mass: {nominal} kg -> {} kg",
        nominal * 1.05
    );
    println!(
        "largest change of M(q): {:.6e} kg·m²",
        (perturbed_mass - nominal_mass).amax()
    );
    for (i, joint) in model.joints.iter().enumerate() {
        println!(
            "  gravity torque {:<24} {:>12.6} -> {:>12.6}",
            joint.name, nominal_gravity[i], perturbed_gravity[i]
        );
    }
    Ok(())
}
