//! Helpers shared by the integration tests (`mod common;`): the ribbon binary, running it for
//! JSON, and the Python reference tools (Pinocchio, example-robot-data) in a venv under the
//! target directory.
//!
//! The venv is made once per target directory, under a file lock, since cargo runs test binaries
//! and test threads in parallel. A stamp file holding the text of `tests/reference/requirements.txt`
//! marks a finished install: a half-finished one (no stamp) is redone from scratch, and a changed
//! requirements file reinstalls. Every failure panics with the command, its exit status and the
//! tail of its output: a cross-check never skips in silence.

#![allow(dead_code)]

use std::fs::{self, File};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Lines of a failing command's stderr (and stdout) quoted in the panic message.
const OUTPUT_TAIL_LINES: usize = 40;

/// The crate root.
pub fn manifest_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A path inside the crate root (`robots/ur5/ur5.urdf` → `<crate root>/robots/ur5/ur5.urdf`).
pub fn manifest(path: &str) -> PathBuf {
    manifest_dir().join(path)
}

/// `CARGO_TARGET_DIR` (relative to the crate root when relative) or `<crate root>/target`.
pub fn target_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR")
        .or_else(|| option_env!("CARGO_TARGET_DIR").map(Into::into))
    {
        Some(dir) if !dir.is_empty() => manifest_dir().join(dir),
        _ => manifest_dir().join("target"),
    }
}

/// The `ribbon` binary cargo built for this test run.
pub fn ribbon_bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_ribbon"))
}

/// A command as one shell-pasteable line (for panic messages and reproductions).
pub fn shell_line(program: &Path, args: &[String]) -> String {
    fn quote(s: &str) -> String {
        if !s.is_empty()
            && s.chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_./=,:+@%".contains(c))
        {
            s.to_string()
        } else {
            format!("'{}'", s.replace('\'', r"'\''"))
        }
    }
    std::iter::once(quote(&program.display().to_string()))
        .chain(args.iter().map(|a| quote(a)))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The last `n` lines of `bytes`, as text.
pub fn tail(bytes: &[u8], n: usize) -> String {
    let text = String::from_utf8_lossy(bytes);
    let lines: Vec<&str> = text.lines().collect();
    let start = lines.len().saturating_sub(n);
    let mut out = lines[start..].join("\n");
    if start > 0 {
        out = format!("[… {start} earlier lines]\n{out}");
    }
    out
}

fn describe_status(status: &ExitStatus) -> String {
    match status.code() {
        Some(code) => format!("exit code {code}"),
        None => {
            #[cfg(unix)]
            {
                use std::os::unix::process::ExitStatusExt;
                if let Some(signal) = status.signal() {
                    return format!("killed by signal {signal}");
                }
            }
            "no exit code".to_string()
        }
    }
}

/// Runs a command to completion; panics (with stderr and stdout tails) if it cannot start or
/// does not exit 0.
pub fn run_checked(program: &Path, args: &[String], what: &str) -> Output {
    let output = Command::new(program)
        .args(args)
        .current_dir(manifest_dir())
        .stdin(Stdio::null())
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "{what}: could not start `{}`: {e}",
                shell_line(program, args)
            )
        });
    if !output.status.success() {
        panic!(
            "{what} failed\n  command: {}\n  status: {}\n  stderr (tail):\n{}\n  stdout (tail):\n{}",
            shell_line(program, args),
            describe_status(&output.status),
            tail(&output.stderr, OUTPUT_TAIL_LINES),
            tail(&output.stdout, OUTPUT_TAIL_LINES),
        );
    }
    output
}

/// The outcome of a command that ran to its end or was killed at its time limit.
pub struct Finished {
    pub status: Option<ExitStatus>,
    pub stdout: Vec<u8>,
    pub stderr: Vec<u8>,
    pub timed_out: bool,
    pub elapsed: Duration,
}

/// Runs a command with a time limit (a hang is a failure to report, not a stuck test run).
pub fn run_with_timeout(program: &Path, args: &[String], limit: Duration) -> Finished {
    let start = Instant::now();
    let mut child = Command::new(program)
        .args(args)
        .current_dir(manifest_dir())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("could not start `{}`: {e}", shell_line(program, args)));
    // Drain both pipes on threads so that a chatty child never blocks on a full pipe.
    let mut out_pipe = child.stdout.take().expect("piped stdout");
    let mut err_pipe = child.stderr.take().expect("piped stderr");
    let out_thread = std::thread::spawn(move || {
        let mut buf = Vec::new();
        let _ = out_pipe.read_to_end(&mut buf);
        buf
    });
    let err_thread = std::thread::spawn(move || {
        let mut buf = Vec::new();
        let _ = err_pipe.read_to_end(&mut buf);
        buf
    });
    let mut timed_out = false;
    let status = loop {
        match child.try_wait().expect("waiting for a child process") {
            Some(status) => break Some(status),
            None if start.elapsed() > limit => {
                timed_out = true;
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
            None => std::thread::sleep(Duration::from_millis(5)),
        }
    };
    Finished {
        status,
        stdout: out_thread.join().unwrap_or_default(),
        stderr: err_thread.join().unwrap_or_default(),
        timed_out,
        elapsed: start.elapsed(),
    }
}

/// Runs `ribbon ARGS`, which must exit 0, and parses its stdout as JSON.
pub fn ribbon_json(args: &[String]) -> serde_json::Value {
    let bin = ribbon_bin();
    let output = run_checked(&bin, args, "ribbon");
    serde_json::from_slice(&output.stdout).unwrap_or_else(|e| {
        panic!(
            "ribbon printed invalid JSON ({e})\n  command: {}\n  stdout (tail):\n{}",
            shell_line(&bin, args),
            tail(&output.stdout, OUTPUT_TAIL_LINES)
        )
    })
}

/// Converts `&str`s to the owned argument list the helpers take.
pub fn args<I, S>(items: I) -> Vec<String>
where
    I: IntoIterator<Item = S>,
    S: Into<String>,
{
    items.into_iter().map(Into::into).collect()
}

/// A comma-separated vector for `--q=…` and friends; `{}` on f64 prints the shortest text that
/// reads back to the same number, so nothing is lost on the way.
pub fn csv(values: &[f64]) -> String {
    values
        .iter()
        .map(|x| format!("{x}"))
        .collect::<Vec<_>>()
        .join(",")
}

/// FNV-1a 64-bit hash as 16 hex digits (tests/reference/pin_dynamics.py computes the same).
pub fn fnv1a64(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// The requirements file of the reference venv.
pub fn requirements_path() -> PathBuf {
    manifest_dir().join("tests/reference/requirements.txt")
}

/// The Python interpreter of the reference venv (`<target dir>/reference-venv/bin/python`),
/// created and installed on first use (`python3 -m venv`, `pip install -r
/// tests/reference/requirements.txt`; measured: 15 s and 0.9 GB for Pinocchio and
/// example-robot-data alone, under a minute with the MCAP and rerun tools). Panics, loudly and
/// precisely, if that fails.
pub fn reference_python() -> PathBuf {
    static PYTHON: OnceLock<PathBuf> = OnceLock::new();
    PYTHON.get_or_init(create_reference_venv).clone()
}

// Uses `File::lock` (stable since Rust 1.89, the crate's declared minimum).
fn create_reference_venv() -> PathBuf {
    let target = target_dir();
    let venv = target.join("reference-venv");
    let stamp = target.join("reference-venv.stamp");
    let lock_path = target.join("reference-venv.lock");
    let python = venv.join("bin").join("python");
    let requirements_file = requirements_path();
    let requirements = fs::read_to_string(&requirements_file).unwrap_or_else(|e| {
        panic!(
            "reference venv: cannot read {}: {e}",
            requirements_file.display()
        )
    });

    fs::create_dir_all(&target)
        .unwrap_or_else(|e| panic!("reference venv: cannot create {}: {e}", target.display()));
    let lock = File::options()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .unwrap_or_else(|e| {
            panic!(
                "reference venv: cannot open the lock file {}: {e}",
                lock_path.display()
            )
        });
    // Blocks while another test binary installs; released when `lock` is dropped (or the
    // process dies), so a crashed install never leaves the lock held.
    lock.lock()
        .unwrap_or_else(|e| panic!("reference venv: cannot lock {}: {e}", lock_path.display()));

    let installed = fs::read_to_string(&stamp)
        .map(|s| s == requirements)
        .unwrap_or(false);
    if installed && python.exists() {
        return python;
    }

    // Not installed, half-installed, or installed from another requirements file: start over.
    let _ = fs::remove_file(&stamp);
    if venv.exists() {
        fs::remove_dir_all(&venv).unwrap_or_else(|e| {
            panic!(
                "reference venv: cannot remove the stale venv {}: {e}",
                venv.display()
            )
        });
    }
    eprintln!(
        "reference venv: creating {} from {} (once per target dir; under a minute)",
        venv.display(),
        requirements_file.display()
    );
    let system_python =
        PathBuf::from(std::env::var_os("RIBBON_PYTHON").unwrap_or_else(|| "python3".into()));
    run_checked(
        &system_python,
        &args([
            "-m".to_string(),
            "venv".to_string(),
            venv.display().to_string(),
        ]),
        "reference venv: creating the venv",
    );
    run_checked(
        &python,
        &args([
            "-m".to_string(),
            "pip".to_string(),
            "install".to_string(),
            "--disable-pip-version-check".to_string(),
            "--no-input".to_string(),
            "-r".to_string(),
            requirements_file.display().to_string(),
        ]),
        "reference venv: pip install -r tests/reference/requirements.txt",
    );
    let tmp = stamp.with_extension("stamp.tmp");
    fs::write(&tmp, &requirements)
        .and_then(|()| fs::rename(&tmp, &stamp))
        .unwrap_or_else(|e| {
            panic!(
                "reference venv: cannot write the stamp {}: {e}",
                stamp.display()
            )
        });
    drop(lock);
    python
}

/// example-robot-data's `robots` directory inside the reference venv.
pub fn example_robot_data_dir() -> PathBuf {
    let python = reference_python();
    let script = manifest_dir().join("tests/reference/pin_dynamics.py");
    let out = run_checked(
        &python,
        &args([script.display().to_string(), "--erd-dir".to_string()]),
        "locating example-robot-data",
    );
    let dir = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
    assert!(
        dir.is_dir(),
        "example-robot-data's robots directory {} does not exist",
        dir.display()
    );
    dir
}

/// Every file under `dir` whose name ends with `.{ext}`, sorted.
pub fn files_with_extension(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries =
            fs::read_dir(&d).unwrap_or_else(|e| panic!("cannot list {}: {e}", d.display()));
        for entry in entries {
            let path = entry
                .unwrap_or_else(|e| panic!("cannot list {}: {e}", d.display()))
                .path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == ext) {
                found.push(path);
            }
        }
    }
    found.sort();
    found
}

/// A shipped robot and its sidecar (paths relative to the crate root) loaded the way `analyze` loads
/// them (`ribbon::setup::Setup::load`: model with the scene's gravity, scene, parameter box, start
/// check), with `[scene] duration` overridden to `duration_s`. Panics naming the files on failure.
pub fn shipped_setup(urdf: &str, sidecar: &str, duration_s: f64) -> ribbon::setup::Setup {
    let (urdf_path, sidecar_path) = (manifest_dir().join(urdf), manifest_dir().join(sidecar));
    let request = ribbon::setup::SetupRequest {
        urdf: &urdf_path,
        uncertainty: Some(&sidecar_path),
        floating: false,
        overrides: ribbon::scene::SceneOverrides {
            duration_s: Some(duration_s),
            ..ribbon::scene::SceneOverrides::default()
        },
    };
    ribbon::setup::Setup::load(&request, &mut |_, _| {})
        .unwrap_or_else(|e| panic!("{urdf} with {sidecar}: {e}"))
}

/// The shipped slider-crank's sidecar with its rod shorter than its crank at one end of the box
/// (`l` ∈ [0.05, 0.404] m, `r` ∈ [0.0999, 0.1001] m), written into `dir`: past the crank angle
/// where `r sin θ = l` the loop cannot close whatever the step, so such samples fail at the fixed
/// step and with the adaptive step alike (issue 39 item 5). Returns the sidecar's path.
pub fn short_rod_slider_crank_sidecar(dir: &Path) -> PathBuf {
    let shipped = fs::read_to_string(manifest(
        "robots/slider_crank/slider_crank.uncertainty.toml",
    ))
    .expect("the shipped slider-crank sidecar reads");
    let text = shipped
        .replace("r = [0.099, 0.101]", "r = [0.0999, 0.1001]")
        .replace("l = [0.396, 0.404]", "l = [0.05, 0.404]");
    assert_ne!(text, shipped, "the rod and crank intervals are replaced");
    let path = dir.join("short_rod.uncertainty.toml");
    fs::write(&path, text).expect("write the short-rod sidecar");
    path
}

/// A study summary's series `key` (`lower`, `upper`, `runs_lower`, `time`, …) of output `output`.
/// Panics naming the output or key when the summary has none.
pub fn summary_series(summary: &serde_json::Value, output: &str, key: &str) -> Vec<f64> {
    summary["outputs"]
        .as_array()
        .expect("the summary has outputs")
        .iter()
        .find(|o| o["name"] == output)
        .unwrap_or_else(|| panic!("no output {output}"))[key]
        .as_array()
        .unwrap_or_else(|| panic!("{output}: no {key}"))
        .iter()
        .map(|x| x.as_f64().expect("a number"))
        .collect()
}

/// The summary fields that depend on the machine and the moment, not on the study.
pub const TIMING_FIELDS: [&str; 5] = [
    "simulate_seconds",
    "bound_seconds",
    "phase_seconds",
    "threads",
    "peak_memory_bytes",
];

/// A summary's JSON text with `wall_seconds` and the [`TIMING_FIELDS`] present in `stats` set to
/// null, re-serialised (exact: serde_json's float_roundtrip), for comparing two runs' summaries.
pub fn masked_summary(text: &str) -> String {
    let mut value: serde_json::Value = serde_json::from_str(text).expect("summary is JSON");
    value["wall_seconds"] = serde_json::Value::Null;
    if let Some(stats) = value.get_mut("stats").and_then(|s| s.as_object_mut()) {
        for field in TIMING_FIELDS {
            if stats.contains_key(field) {
                stats.insert(field.to_string(), serde_json::Value::Null);
            }
        }
    }
    serde_json::to_string_pretty(&value).expect("serialise")
}

/// [`masked_summary`] of the summary file at `path`.
pub fn masked_summary_file(path: &Path) -> String {
    masked_summary(&std::fs::read_to_string(path).expect("read summary"))
}

/// A stdout table with the `…, 0.045 s wall` figure replaced by `X s wall`.
pub fn masked_table(text: &str) -> String {
    text.lines()
        .map(|line| match line.find(" s wall") {
            Some(end) => {
                let start = line[..end].rfind(' ').map_or(0, |i| i + 1);
                format!("{}X{}", &line[..start], &line[end..])
            }
            None => line.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// What one run of the `ribbon` binary ended with: its exit code (`None` when killed by a signal)
/// and its stdout and stderr as text (invalid UTF-8 replaced).
#[derive(Debug)]
pub struct Outcome {
    /// The exit code, `None` when a signal ended the process.
    pub code: Option<i32>,
    /// Standard output, lossily decoded.
    pub stdout: String,
    /// Standard error, lossily decoded.
    pub stderr: String,
}

/// Runs the `ribbon` binary with `args` in the crate root and returns its raw [`Output`].
pub fn ribbon_output(args: &[&str]) -> Output {
    Command::new(ribbon_bin())
        .args(args)
        .current_dir(manifest_dir())
        .output()
        .expect("the ribbon binary runs")
}

/// [`ribbon_output`] with the scheduler's shard-index variables (`SLURM_ARRAY_TASK_ID`,
/// `JOB_COMPLETION_INDEX`) removed from its environment, so that a test run inside a Slurm or
/// Kubernetes job does not pick a shard by accident.
pub fn ribbon_output_outside_scheduler(args: &[&str]) -> Output {
    Command::new(ribbon_bin())
        .current_dir(manifest_dir())
        .args(args)
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("JOB_COMPLETION_INDEX")
        .output()
        .expect("the ribbon binary runs")
}

/// [`ribbon_output`] as an [`Outcome`] (exit code and text), for tests that compare messages.
pub fn ribbon_outcome(args: &[&str]) -> Outcome {
    let output = ribbon_output(args);
    Outcome {
        code: output.status.code(),
        stdout: String::from_utf8_lossy(&output.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&output.stderr).into_owned(),
    }
}

/// The scratch directory of one test file, `CARGO_TARGET_TMPDIR/SUITE`, created if missing and
/// kept between runs (its files are overwritten by the next run).
pub fn scratch_dir(suite: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(suite);
    fs::create_dir_all(&dir).expect("create the scratch directory");
    dir
}

/// The path `NAME` in [`scratch_dir`]`(SUITE)` (the directory is created; the file is not).
pub fn scratch_file(suite: &str, name: &str) -> PathBuf {
    scratch_dir(suite).join(name)
}

/// An empty directory for one test, `CARGO_TARGET_TMPDIR/SUITE/TEST`: whatever an earlier run left
/// there is removed first.
pub fn fresh_scratch_dir(suite: &str, test: &str) -> PathBuf {
    emptied(
        PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
            .join(suite)
            .join(test),
    )
}

/// An empty directory `<crate root>/target/test-scratch/SUITE/NAME` (the path the bitwise and
/// shard tests print for inspection), emptied first like [`fresh_scratch_dir`].
pub fn fresh_test_scratch_dir(suite: &str, name: &str) -> PathBuf {
    emptied(manifest("target/test-scratch").join(suite).join(name))
}

fn emptied(dir: PathBuf) -> PathBuf {
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("create the scratch directory");
    dir
}

/// The variable by which a person lets the tests change this machine (install Debian packages
/// with apt-get, as root) outside CI: `RIBBON_TEST_INSTALL=1`.
pub const INSTALL_OPT_IN: &str = "RIBBON_TEST_INSTALL";

/// Whether a test may install system packages: on a CI machine (`CI` set, as `.ci/run` and CI
/// services set it, and not `false` or `0`) or when the person running the tests opted in
/// ([`INSTALL_OPT_IN`]`=1`). Otherwise a test that lacks a system program fails, naming the
/// command that opts in: system-changing set-up never happens in a default `cargo test`.
pub fn system_install_allowed() -> bool {
    let set =
        |name: &str| std::env::var(name).is_ok_and(|v| !v.is_empty() && v != "0" && v != "false");
    set("CI") || set(INSTALL_OPT_IN)
}

/// Whether `program` is on `PATH`.
pub fn have_program(program: &str) -> bool {
    Command::new("sh")
        .arg("-c")
        .arg(format!("command -v {program}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// How long [`ensure_system_programs`]' `apt-get` waits for another apt's lock, seconds.
const APT_LOCK_WAIT_SECONDS: u32 = 600;

/// Makes sure every one of `programs` is on `PATH`: when one is missing and
/// [`system_install_allowed`], installs the Debian `packages` (`apt-get install -y`, as root);
/// when it is not allowed, or the install fails, panics with the exact commands: the one that
/// opts in to the install, and the install itself. `test` is the test file's name (`slurm`).
pub fn ensure_system_programs(test: &str, programs: &[&str], packages: &[&str]) {
    // One install at a time in this test binary: its tests run in parallel, and on a fresh
    // machine two of them found chromium missing at once, and the second `apt-get` failed on
    // the first one's lock. The second now waits, then finds the programs installed.
    static INSTALLING: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _one_at_a_time = INSTALLING
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let missing: Vec<&str> = programs
        .iter()
        .copied()
        .filter(|p| !have_program(p))
        .collect();
    if missing.is_empty() {
        return;
    }
    // Another process's apt (another test binary, the system's own updates) is waited for, up to
    // APT_LOCK_WAIT_SECONDS, rather than failed on.
    let install = format!(
        "apt-get -o DPkg::Lock::Timeout={APT_LOCK_WAIT_SECONDS} update && \
         DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout={APT_LOCK_WAIT_SECONDS} \
         install -y {}",
        packages.join(" ")
    );
    if !system_install_allowed() {
        panic!(
            "{test}: {} not installed, and this test installs system packages only on CI (CI=1) \
             or when you opt in. Either run\n    {INSTALL_OPT_IN}=1 cargo test --release --test \
             {test}\n(it runs `{install}` as root), or install them yourself:\n    sudo sh -c \
             '{install}'",
            missing.join(", ")
        );
    }
    eprintln!("{test}: installing {} ({install})", packages.join(" "));
    let status = Command::new("sh").arg("-c").arg(&install).status();
    let still_missing: Vec<&str> = programs
        .iter()
        .copied()
        .filter(|p| !have_program(p))
        .collect();
    assert!(
        status.is_ok_and(|s| s.success()) && still_missing.is_empty(),
        "{test}: {} could not be installed here (not root?); run as root:\n    {install}\nthen \
         run `cargo test --release --test {test}` again",
        missing.join(", ")
    );
}

/// The error a command printed: its `error:` headline and the indented lines of details under it
/// (`ribbon::text::laid_out`), joined by newlines; empty when there is none.
pub fn error_block(stderr: &str) -> String {
    let mut lines = stderr.lines().skip_while(|l| !l.starts_with("error:"));
    let Some(headline) = lines.next() else {
        return String::new();
    };
    std::iter::once(headline)
        .chain(lines.take_while(|l| l.starts_with("  ")))
        .collect::<Vec<_>>()
        .join("\n")
}

/// A binary STL of `triangles`.
pub fn binary_stl(triangles: &[[[f32; 3]; 3]]) -> Vec<u8> {
    let mut bytes = vec![0u8; 80];
    bytes.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    for triangle in triangles {
        bytes.extend_from_slice(&[0u8; 12]); // normal: recomputed by readers
        for vertex in triangle {
            for x in vertex {
                bytes.extend_from_slice(&x.to_le_bytes());
            }
        }
        bytes.extend_from_slice(&[0u8; 2]);
    }
    bytes
}

/// The 12 outward triangles of the cube `[-h, h]³`.
pub fn cube(h: f32) -> Vec<[[f32; 3]; 3]> {
    let c = |i: usize| {
        [
            if i & 1 == 0 { -h } else { h },
            if i & 2 == 0 { -h } else { h },
            if i & 4 == 0 { -h } else { h },
        ]
    };
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    quads
        .iter()
        .flat_map(|q| [[c(q[0]), c(q[1]), c(q[2])], [c(q[0]), c(q[2]), c(q[3])]])
        .collect()
}

/// A bar on a spring hinge (k = 100 N·m/rad, no gravity, released from 0.3 rad, 5 s; the
/// sidecar [`NINE_DECADE_SIDECAR`]): its URDF.
pub const SPRING_URDF: &str = r#"<?xml version="1.0"?>
<robot name="spring">
  <link name="base"/>
  <link name="bar">
    <inertial>
      <origin xyz="0.5 0 0"/>
      <mass value="1.0"/>
      <inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
  <joint name="hinge" type="continuous">
    <parent link="base"/>
    <child link="bar"/>
    <axis xyz="0 0 1"/>
  </joint>
</robot>
"#;

/// The spring bar's sidecar: its mass over eleven decades, [0.01, 1e9] kg, whose period
/// spreads from 0.04 s to 10 000 s (tests/check_every_method.rs, tests/elements.rs).
pub const NINE_DECADE_SIDECAR: &str = r#"[parameters]
"link.bar.mass" = [0.01, 1e9]
[scene]
duration = 5.0
gravity = [0.0, 0.0, 0.0]
effects = ["joint_springs"]
initial.q = { hinge = 0.3 }
[[scene.spring]]
joint = "hinge"
stiffness = 100.0
rest = 0.0
[outputs]
joints = "all"
velocities = true
accelerations = true
"#;

/// A staged study as a cluster runs it: `ribbon plan PLAN_ARGS --plan DIR/study.plan`, then stage
/// after stage `ribbon run` in two shards and `ribbon merge` (writing `DIR/merge.json` and
/// `DIR/merge.csv`) until merge stops asking for a stage (exit 3). Every merge's outcome, in
/// order; panics when a step fails or merge asks for more than `max_stages` stages.
pub fn plan_run_merge_in_two_shards(
    dir: &Path,
    plan_args: &[&str],
    max_stages: usize,
) -> Vec<Outcome> {
    let path = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let (plan, shards) = (path("study.plan"), path("shards"));
    let mut args = vec!["plan"];
    args.extend_from_slice(plan_args);
    args.extend_from_slice(&["--plan", &plan]);
    let planned = ribbon_outcome(&args);
    assert_eq!(planned.code, Some(0), "{}", planned.stderr);
    let mut merges = Vec::new();
    loop {
        for shard in ["0/2", "1/2"] {
            let run = ribbon_outcome(&["run", &plan, "--shard", shard, "--into", &shards]);
            assert_eq!(run.code, Some(0), "{}", run.stderr);
        }
        let merged = ribbon_outcome(&[
            "merge",
            &plan,
            &shards,
            "--summary",
            &path("merge.json"),
            "--csv",
            &path("merge.csv"),
        ]);
        let asks = merged.code == Some(3);
        merges.push(merged);
        if !asks {
            return merges;
        }
        assert!(merges.len() <= max_stages, "merge keeps asking for stages");
    }
}

/// The `ribbon` metadata record of the MCAP log `bytes` (read through its summary section).
pub fn ribbon_metadata(bytes: &[u8]) -> std::collections::BTreeMap<String, String> {
    let summary = mcap::Summary::read(bytes)
        .unwrap()
        .expect("a summary section");
    let index = summary
        .metadata_indexes
        .iter()
        .find(|m| m.name == "ribbon")
        .expect("a `ribbon` metadata record");
    mcap::read::metadata(bytes, index).unwrap().metadata
}
