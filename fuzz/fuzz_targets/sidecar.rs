//! The sidecar on arbitrary text, resolved against a fixed robot the way `ribbon analyze` prepares
//! a study: TOML parse, base type, scene resolution, parameter space (with its box check). The
//! first byte picks the robot (ur5 or the slider-crank, which has loops and a drive).
#![no_main]

use libfuzzer_sys::fuzz_target;
use ribbon::model::{LoadOptions, Model};
use ribbon::scene::{parse_sidecar, wants_floating_base, Scene, SceneOverrides};
use ribbon::uncertainty::ParameterSpace;

const ROBOTS: [(&str, &str); 2] = [
    ("ur5.urdf", include_str!("../../robots/ur5/ur5.urdf")),
    (
        "slider_crank.urdf",
        include_str!("../../robots/slider_crank/slider_crank.urdf"),
    ),
];

fuzz_target!(|data: &[u8]| {
    let Some((&pick, bytes)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(bytes) else {
        return;
    };
    let Ok(sidecar) = parse_sidecar(text) else {
        return;
    };
    let Ok(floating_base) = wants_floating_base(&sidecar, "fuzz.toml") else {
        return;
    };
    let (name, urdf) = ROBOTS[usize::from(pick) % ROBOTS.len()];
    let Ok(mut model) = Model::from_urdf_str(urdf, name, LoadOptions { floating_base }) else {
        return;
    };
    let Ok(scene) = Scene::resolve(&sidecar, &model, "fuzz.toml", SceneOverrides::default()) else {
        return;
    };
    let mut environment = scene.environment();
    if let Ok(space) = ParameterSpace::from_sidecar(&sidecar, &model, &environment, "fuzz.toml") {
        let xi = space.nominal_xi();
        space.apply(&mut model, &mut environment, &xi);
    }
});
