//! Issue 12: deeply nested XML overflowed the stack (`ribbon params` aborted with exit 134). The
//! depth is now measured by an iterative scan before parsing (`ribbon::model::MAX_XML_DEPTH`);
//! these reproducers must exit 2 with a message naming the file and line, through the binary
//! (whose main thread has the stack a user gets).

mod common;

use std::time::Duration;

/// Parsing 100 000 nested elements is a linear scan; a run still going after this is a hang.
const CALL_TIME_LIMIT: Duration = Duration::from_secs(60);

fn run_params(name: &str, text: &str) -> (Option<i32>, String) {
    let dir = common::target_dir().join("issue-12-deep-xml");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    let args = common::args(["params".to_string(), path.display().to_string()]);
    let done = common::run_with_timeout(&common::ribbon_bin(), &args, CALL_TIME_LIMIT);
    assert!(
        !done.timed_out,
        "{name}: still running after {CALL_TIME_LIMIT:?}"
    );
    (
        done.status.and_then(|s| s.code()),
        String::from_utf8_lossy(&done.stderr).into_owned(),
    )
}

#[test]
fn one_hundred_thousand_nested_elements_are_refused_not_a_stack_overflow() {
    let depth = 100_000;
    let text = format!(
        "<robot name=\"r\">\n<link name=\"a\">\n{}{}</link></robot>\n",
        "<x>".repeat(depth),
        "</x>".repeat(depth)
    );
    let (code, stderr) = run_params("deep.urdf", &text);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "deep.urdf:3: <x> is nested {} elements deep",
            ribbon::model::MAX_XML_DEPTH + 1
        )),
        "{stderr}"
    );
}

#[test]
fn unclosed_nesting_and_entity_expansion_are_bounded_too() {
    // Opening tags that never close: refused by the depth scan, not by a recursive parser.
    let (code, stderr) = run_params(
        "unclosed.urdf",
        &format!("<robot name=\"r\">{}", "<x>".repeat(100_000)),
    );
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("unclosed.urdf:1: <x> is nested"),
        "{stderr}"
    );
    // Markup hidden in an entity, expanded by the parser: counted from the DOCTYPE.
    let nested = format!("{}{}", "<y>".repeat(300), "</y>".repeat(300));
    let text = format!(
        "<!DOCTYPE robot [<!ENTITY deep \"{nested}\">]>\n<robot name=\"r\"><link name=\"a\">&deep;</link></robot>"
    );
    let (code, stderr) = run_params("entity.urdf", &text);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("entity.urdf:2: <robot> is nested"),
        "{stderr}"
    );
}
