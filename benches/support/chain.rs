//! A generated serial chain of `n` links for the loading benches and tests (issue 39): a massless
//! `base`, then links `l0 … l{n-1}`, each with an `<inertial>` and a revolute joint `j{i}` about y,
//! 0.1 m above its parent, one element per line (as generators write them). Shared through
//! `#[path]` by `benches/chain_loading.rs` and `tests/long_chain.rs`.

#![allow(dead_code)]

/// The URDF text of the chain of `links` links.
pub fn chain_urdf(links: usize) -> String {
    let mut text = String::with_capacity(links * 420 + 64);
    text.push_str(&format!(
        "<robot name=\"chain{links}\">\n<link name=\"base\"/>\n"
    ));
    for i in 0..links {
        let parent = if i == 0 {
            "base".to_string()
        } else {
            format!("l{}", i - 1)
        };
        text.push_str(&format!(
            "<link name=\"l{i}\"><inertial><origin xyz=\"0 0 0.05\"/><mass value=\"0.1\"/><inertia ixx=\"1e-4\" ixy=\"0\" ixz=\"0\" iyy=\"1e-4\" iyz=\"0\" izz=\"1e-5\"/></inertial></link>\n\
             <joint name=\"j{i}\" type=\"revolute\"><parent link=\"{parent}\"/><child link=\"l{i}\"/><origin xyz=\"0 0 0.1\"/><axis xyz=\"0 1 0\"/><limit lower=\"-3\" upper=\"3\" effort=\"10\" velocity=\"10\"/></joint>\n"
        ));
    }
    text.push_str("</robot>\n");
    text
}

/// A sidecar whose `*` patterns make every link's mass and `ixx` and every joint's origin height
/// uncertain (d = 3 × links), with a one-step scene.
pub const CHAIN_SIDECAR: &str = "[parameters]\n\"link.*.mass\" = { rel = 0.1 }\n\"link.*.inertia.ixx\" = { rel = 0.1 }\n\"joint.*.origin.z\" = { abs = 0.001 }\n\n[scene]\nduration = 0.001\nstep = 0.001\n";
