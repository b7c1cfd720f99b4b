//! Every URDF that example-robot-data 5.0.0 ships (77 files, from the reference venv): `ribbon params
//! URDF --json` and `ribbon dynamics URDF --json` must each either succeed with consistent, finite
//! JSON or refuse with exit code 2 and a stderr message that names the file. Never a panic
//! (exit 101), a signal, another exit code or a hang. Prints the counts, with the refusal reasons
//! (`-- --nocapture` to see them on success), and writes them to
//! `<target dir>/example-robot-data-smoke.txt`.

mod common;

use serde_json::Value;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

/// The URDF files example-robot-data 5.0.0 ships (`find … -name '*.urdf' | wc -l`).
const EXPECTED_URDF_COUNT: usize = 77;

/// Files that must load: all but the two that are broken as shipped (below). Without a floor a
/// reader that refused everything with a clear message would pass.
const MIN_LOADED: usize = 75;

/// The files example-robot-data 5.0.0 ships broken, which ribbon must refuse: `falcon.urdf` names a
/// child link it does not define (`Z_propeller`), `ur3.urdf` has no `<link>` at all.
const KNOWN_BROKEN: [&str; 2] = [
    "falcon_description/urdf/falcon.urdf",
    "ur_description/urdf/ur3.urdf",
];

/// Exit code for bad arguments or bad input (the design's exit codes).
const EXIT_BAD_INPUT: i32 = 2;

/// One ribbon call on the largest of these robots takes well under a second in release; a call
/// still running after this long is a hang.
const CALL_TIME_LIMIT: Duration = Duration::from_secs(60);

/// Whether the URDF has a `<texture>` without `filename` (urdf-rs rejects those; real-world input
/// that ribbon must load: romeo_laas_small, icub, icub_reduced).
fn has_texture_without_filename(urdf: &Path) -> bool {
    let text = std::fs::read_to_string(urdf).unwrap_or_default();
    text.match_indices("<texture").any(|(at, _)| {
        let tag = &text[at..];
        let end = tag.find('>').unwrap_or(tag.len());
        !tag[..end].contains("filename")
    })
}

/// How one subcommand went on one file.
enum Outcome {
    Loaded,
    Refused(String),
    Broken(String),
}

fn run(subcommand: &str, urdf: &Path) -> Outcome {
    let args = vec![
        subcommand.to_string(),
        urdf.display().to_string(),
        "--json".to_string(),
    ];
    let bin = common::ribbon_bin();
    let command = common::shell_line(&bin, &args);
    let done = common::run_with_timeout(&bin, &args, CALL_TIME_LIMIT);
    let stderr = String::from_utf8_lossy(&done.stderr).trim().to_string();
    if done.timed_out {
        return Outcome::Broken(format!(
            "still running after {CALL_TIME_LIMIT:?}, killed\n    {command}"
        ));
    }
    let status = done.status.expect("finished");
    match status.code() {
        Some(0) => match serde_json::from_slice::<Value>(&done.stdout) {
            Ok(json) => match if subcommand == "params" {
                check_params(&json)
            } else {
                check_dynamics(&json)
            } {
                Ok(()) => Outcome::Loaded,
                Err(e) => {
                    Outcome::Broken(format!("exit 0 but inconsistent JSON: {e}\n    {command}"))
                }
            },
            Err(e) => Outcome::Broken(format!("exit 0 but invalid JSON ({e})\n    {command}")),
        },
        Some(EXIT_BAD_INPUT) => {
            let file_name = urdf.file_name().unwrap().to_string_lossy();
            if stderr.is_empty() {
                Outcome::Broken(format!("exit 2 with an empty stderr\n    {command}"))
            } else if !stderr.contains(file_name.as_ref()) {
                Outcome::Broken(format!(
                    "exit 2 but stderr does not name the file {file_name}: {stderr}\n    {command}"
                ))
            } else {
                Outcome::Refused(stderr)
            }
        }
        Some(101) => Outcome::Broken(format!(
            "PANIC (exit 101): {}\n    {command}",
            common::tail(&done.stderr, 10)
        )),
        Some(code) => Outcome::Broken(format!(
            "exit code {code} (expected 0 or 2): {stderr}\n    {command}"
        )),
        None => Outcome::Broken(format!(
            "CRASH: no exit code ({status:?}): {stderr}\n    {command}"
        )),
    }
}

fn finite(value: &Value) -> bool {
    match value {
        Value::Number(n) => n.as_f64().is_some_and(f64::is_finite),
        Value::Array(items) => items.iter().all(finite),
        Value::Object(map) => map.values().all(finite),
        _ => true,
    }
}

fn check_params(json: &Value) -> Result<(), String> {
    let params = json.as_array().ok_or("not a list")?;
    for p in params {
        p["path"]
            .as_str()
            .ok_or_else(|| format!("parameter without a path: {p}"))?;
        p["unit"]
            .as_str()
            .ok_or_else(|| format!("parameter without a unit: {p}"))?;
        let nominal = p["nominal"]
            .as_f64()
            .ok_or_else(|| format!("parameter without a numeric nominal: {p}"))?;
        if !nominal.is_finite() {
            return Err(format!("non-finite nominal: {p}"));
        }
    }
    Ok(())
}

fn check_dynamics(json: &Value) -> Result<(), String> {
    let nq = json["nq"].as_u64().ok_or("no nq")? as usize;
    let nv = json["nv"].as_u64().ok_or("no nv")? as usize;
    let (mut q_at, mut v_at) = (0, 0);
    for j in json["joints"].as_array().ok_or("no joints list")? {
        let get = |k: &str| {
            j[k].as_u64()
                .map(|x| x as usize)
                .ok_or_else(|| format!("joint without {k}: {j}"))
        };
        let (jq, jv) = (get("nq")?, get("nv")?);
        if jq == 0 && jv == 0 {
            continue;
        }
        if get("q_index")? != q_at || get("v_index")? != v_at {
            return Err(format!(
                "joint {j} does not start where the previous one ended (q {q_at}, v {v_at})"
            ));
        }
        q_at += jq;
        v_at += jv;
    }
    if (q_at, v_at) != (nq, nv) {
        return Err(format!(
            "joints cover nq={q_at} nv={v_at}, JSON says nq={nq} nv={nv}"
        ));
    }
    let m = json["mass_matrix"].as_array().ok_or("no mass_matrix")?;
    if m.len() != nv || m.iter().any(|row| row.as_array().map(Vec::len) != Some(nv)) {
        return Err(format!("mass_matrix is not {nv}×{nv}"));
    }
    if json["bias"].as_array().map(Vec::len) != Some(nv) {
        return Err(format!("bias is not of length {nv}"));
    }
    let frames = json["frames"].as_object().ok_or("no frames object")?;
    if frames.is_empty() {
        return Err("no frames".into());
    }
    for key in ["mass_matrix", "bias", "frames"] {
        if !finite(&json[key]) {
            return Err(format!("{key} has non-finite numbers"));
        }
    }
    Ok(())
}

#[test]
fn every_example_robot_data_urdf_loads_or_is_refused_clearly() {
    let dir = common::example_robot_data_dir();
    let urdfs = common::files_with_extension(&dir, "urdf");
    assert_eq!(
        urdfs.len(),
        EXPECTED_URDF_COUNT,
        "example-robot-data 5.0.0 ships {EXPECTED_URDF_COUNT} URDFs; found {} under {}",
        urdfs.len(),
        dir.display()
    );

    let mut loaded = Vec::new();
    let mut refused: BTreeMap<String, Vec<String>> = BTreeMap::new(); // reason → files
    let mut broken = Vec::new();
    let mut broken_files = 0;
    let mut textures = 0;
    for urdf in &urdfs {
        let name = urdf.strip_prefix(&dir).unwrap().display().to_string();
        let params = run("params", urdf);
        let dynamics = run("dynamics", urdf);
        let texture = has_texture_without_filename(urdf);
        textures += usize::from(texture);
        match (params, dynamics) {
            (Outcome::Loaded, Outcome::Loaded) => loaded.push(name),
            (Outcome::Refused(a), Outcome::Refused(_)) if texture => {
                broken_files += 1;
                broken.push(format!("{name}: has a <texture/> without filename, which ribbon must load, but was refused: {a}"));
            }
            (Outcome::Refused(a), Outcome::Refused(b)) => {
                // Group by the message with the file's path taken out, so that one cause is one line.
                let path = urdf.display().to_string();
                let reason = |s: &str| {
                    s.replace(&path, "FILE")
                        .lines()
                        .next()
                        .unwrap_or("")
                        .to_string()
                };
                let key = if reason(&a) == reason(&b) {
                    reason(&a)
                } else {
                    format!("params: {} | dynamics: {}", reason(&a), reason(&b))
                };
                refused.entry(key).or_default().push(name);
            }
            (p, d) => {
                broken_files += 1;
                for (sub, outcome) in [("params", p), ("dynamics", d)] {
                    match outcome {
                        Outcome::Broken(e) => broken.push(format!("{name}: {sub}: {e}")),
                        Outcome::Refused(e) => broken.push(format!(
                            "{name}: {sub} refused it while the other subcommand loaded it: {e}"
                        )),
                        Outcome::Loaded => {}
                    }
                }
            }
        }
    }

    let refused_count: usize = refused.values().map(Vec::len).sum();
    let mut report = String::new();
    writeln!(
        report,
        "example-robot-data 5.0.0: {} URDFs: {} loaded, {} clearly refused (exit 2), {broken_files} broken",
        urdfs.len(),
        loaded.len(),
        refused_count,
    )
    .unwrap();
    for (reason, files) in &refused {
        writeln!(
            report,
            "  refused ({}): {reason}\n    {}",
            files.len(),
            files.join("\n    ")
        )
        .unwrap();
    }
    for b in &broken {
        writeln!(report, "  BROKEN: {b}").unwrap();
    }
    std::fs::write(
        common::target_dir().join("example-robot-data-smoke.txt"),
        &report,
    )
    .unwrap();
    println!("{report}");

    assert_eq!(
        textures, 3,
        "example-robot-data 5.0.0 has 3 URDFs with a <texture/> without filename"
    );
    assert_eq!(
        loaded.len() + refused_count + broken_files,
        EXPECTED_URDF_COUNT,
        "every file is counted once"
    );
    assert!(
        broken.is_empty(),
        "{broken_files} URDF(s) made ribbon misbehave:\n{report}"
    );
    assert_eq!(loaded.len() + refused_count, EXPECTED_URDF_COUNT);
    assert!(
        loaded.len() >= MIN_LOADED,
        "only {} of {EXPECTED_URDF_COUNT} files loaded (at least {MIN_LOADED} must):\n{report}",
        loaded.len()
    );
    let mut refused_files: Vec<&str> = refused.values().flatten().map(|f| f.as_str()).collect();
    refused_files.sort_unstable();
    assert_eq!(refused_files, KNOWN_BROKEN, "refused:\n{report}");
}
