//! The URDF loader on arbitrary bytes: `Model::from_urdf_str` with a fixed and a floating base,
//! then the dynamics at the neutral configuration. Any outcome but a panic, a crash or a hang is
//! fine: an error is the loader doing its job.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ribbon::dynamics::{crba, forward_dynamics, forward_kinematics, rnea, Data};
use ribbon::model::{LoadOptions, Model};

fuzz_target!(|data: &[u8]| {
    let Some((&flags, bytes)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(bytes) else {
        return;
    };
    let options = LoadOptions {
        floating_base: flags & 1 == 1,
    };
    let Ok(model) = Model::from_urdf_str(text, "fuzz.urdf", options) else {
        return;
    };
    let mut data = Data::new(&model);
    let q = model.neutral_configuration();
    let zeros = vec![0.0; model.nv];
    forward_kinematics(&model, &mut data, &q);
    crba(&model, &mut data, &q);
    rnea(&model, &mut data, &q, &zeros, &zeros);
    let _ = forward_dynamics(&model, &mut data, &q, &zeros, &zeros);
});
