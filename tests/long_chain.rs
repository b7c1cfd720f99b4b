//! Loading grows linearly with the links (issue 39, item 3): a generated chain of 50 000 links
//! (`benches/support/chain.rs`) loads on a test thread's stack (nothing walks the tree
//! recursively), lists its parameters and expands a box of `*` patterns over every link; the
//! times are in `benches/chain_loading.rs`, not asserted here. The commands that would need its
//! dense `nv × nv` matrices (20 GB each) refuse it with the numbers instead of aborting on the
//! allocation, and `ribbon params` lists it.

#[path = "../benches/support/chain.rs"]
mod chain;
mod common;

use ribbon::environment::Environment;
use ribbon::model::{LoadOptions, Model};
use ribbon::params;
use ribbon::scene::parse_sidecar;
use ribbon::uncertainty::ParameterSpace;

const LINKS: usize = 50_000;

#[test]
fn a_chain_of_50000_links_loads_lists_and_expands() {
    let text = chain::chain_urdf(LINKS);
    let model =
        Model::from_urdf_str(&text, "chain.urdf", LoadOptions::default()).expect("the chain loads");
    assert_eq!(
        (model.nq, model.nv, model.joints.len()),
        (LINKS, LINKS, LINKS)
    );
    // Depth-first coordinates along the chain: joint j{i} moves body i, whose parent is i − 1.
    let last = &model.joints[LINKS - 1];
    assert_eq!(last.name, format!("j{}", LINKS - 1));
    assert_eq!((last.parent, last.q_index), (Some(LINKS - 2), LINKS - 1));
    assert_eq!(model.description.link_index("l49999"), Some(LINKS));
    assert_eq!(model.joint_index("j12345"), Some(12_345));
    // The line of the last joint, counted through the whole file.
    let spec = &model.description.joints[LINKS - 1];
    assert_eq!(spec.line as usize, 2 * LINKS + 2);

    // A chain loaded without a scene: the default environment (standard gravity, no contacts).
    let environment = Environment::default();
    let listed = params::list(&model, &environment);
    // 11 values per link (base included), 11 per revolute joint, 3 of gravity.
    assert_eq!(listed.len(), 11 * (LINKS + 1) + 11 * LINKS + 3);
    assert_eq!(
        params::resolve(&model, &environment, "link.l31415.mass").ok(),
        Some(listed[11 * 31_416].target)
    );

    let sidecar = parse_sidecar(chain::CHAIN_SIDECAR).expect("the sidecar parses");
    let space = ParameterSpace::from_sidecar(&sidecar, &model, &environment, "chain.toml")
        .expect("the box");
    assert_eq!(space.len(), 3 * LINKS);
    assert_eq!(space.box_check().links, LINKS);
}

#[test]
fn the_commands_load_a_chain_of_50000_links_or_refuse_it_with_the_numbers() {
    let dir = common::fresh_scratch_dir("long_chain", "commands");
    let urdf = dir.join("chain.urdf");
    std::fs::write(&urdf, chain::chain_urdf(LINKS)).expect("write the chain");
    let sidecar = dir.join("chain.uncertainty.toml");
    std::fs::write(&sidecar, chain::CHAIN_SIDECAR).expect("write the sidecar");
    let urdf = urdf.to_str().expect("UTF-8 path");
    let sidecar = sidecar.to_str().expect("UTF-8 path");

    let listed = common::ribbon_outcome(&["params", urdf]);
    assert_eq!(listed.code, Some(0), "{}", listed.stderr);
    assert!(
        listed
            .stdout
            .ends_with("1100014 parameters of robot 'chain50000'\n"),
        "{}",
        &listed.stdout[listed.stdout.len().saturating_sub(200)..]
    );
    let boxed = common::ribbon_outcome(&["params", urdf, "--uncertainty", sidecar]);
    assert_eq!(boxed.code, Some(0), "{}", boxed.stderr);

    for args in [
        vec!["dynamics", urdf],
        vec!["simulate", urdf, "--uncertainty", sidecar],
        vec!["analyze", urdf, "--uncertainty", sidecar],
    ] {
        let refused = common::ribbon_outcome(&args);
        assert_eq!(refused.code, Some(2), "{args:?}: {}", refused.stderr);
        assert!(
            refused.stderr.contains("has 50000 velocity coordinates")
                && refused.stderr.contains("MEMORY_BUDGET_BYTES")
                && refused.stderr.contains("ribbon params"),
            "{args:?}: {}",
            refused.stderr
        );
    }
}
