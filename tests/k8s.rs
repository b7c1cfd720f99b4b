//! The shipped Kubernetes manifest (`examples/k8s/ribbon-study.yaml`, issue 14) is a valid Indexed
//! Job, and its pods' command, run as the Job runs it, gives the single-machine bytes.
//!
//! No Kubernetes cluster runs here: this machine has no container runtime, and no registry it
//! reaches ships an API server or a kubelet. What *can* be checked without one is checked:
//! 1. every document of the manifest against the API's own JSON schemas, strictly (unknown fields
//!    refused), for the oldest and the newest Kubernetes the validator knows (`kubernetes-validate`
//!    in the reference venv, through `tests/reference/k8s_job.py`); a misspelt field is refused
//!    (the negative control), so the check can fail;
//! 2. what the API server and ribbon need beyond the schema: `completionMode: Indexed`,
//!    `restartPolicy` `Never`, the shard count of the command equal to `completions`, the
//!    volume a claim of the file with `ReadWriteMany` (pods on several nodes write to it), every
//!    absolute path of the command under the volume's mount;
//! 3. the pods: the container's `command` + `args`, for every index `0..completions`, with the
//!    environment a pod has (`JOB_COMPLETION_INDEX`, `PATH`; nothing of this process's), in a
//!    working directory holding `robots/` as the image does, the mount path standing for a
//!    directory of the test; `parallelism` pods at a time; one pod run again afterwards (a retry
//!    after `backoffLimit`: it overwrites only its own block); then `ribbon merge`, whose CSV,
//!    MCAP and summary (timing fields masked) must equal a single-machine `analyze` of the
//!    study — for the fixed-design study of the manifest's header and for a two-stage screened
//!    study, whose loop (one Job per stage, merge until it exits 0, 3 meaning "next stage
//!    planned") is the one in `examples/k8s/README.md`.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The Kubernetes versions the manifest is validated against: the oldest and the newest schema
/// set `kubernetes-validate` 1.37 ships (Indexed Jobs are stable since 1.24).
const KUBERNETES_VERSIONS: [&str; 2] = ["1.25", "1.37"];

/// The shipped manifest.
const MANIFEST: &str = "examples/k8s/ribbon-study.yaml";

/// The Indexed Job of a manifest, as `k8s_job.py` describes it.
#[derive(serde::Deserialize, Debug)]
struct JobDescription {
    job: String,
    completion_mode: String,
    completions: Option<usize>,
    parallelism: usize,
    backoff_limit: u64,
    restart_policy: String,
    command: Vec<String>,
    args: Vec<String>,
    working_dir: Option<String>,
    env: Vec<EnvVar>,
    mounts: Vec<Mount>,
    claims: Vec<Claim>,
}

#[derive(serde::Deserialize, Debug)]
struct EnvVar {
    name: String,
    value: String,
}

#[derive(serde::Deserialize, Debug)]
struct Mount {
    name: String,
    mount_path: String,
    claim: Option<String>,
}

#[derive(serde::Deserialize, Debug)]
struct Claim {
    name: String,
    access_modes: Vec<String>,
}

/// Runs `k8s_job.py` on `manifest`; the process output (validation failures on stderr).
fn validate(manifest: &Path) -> Output {
    let script = common::manifest("tests/reference/k8s_job.py");
    let mut command = Command::new(common::reference_python());
    command.arg(&script).arg(manifest).arg("--versions");
    command.args(KUBERNETES_VERSIONS);
    command
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", script.display()))
}

fn describe(manifest: &Path) -> JobDescription {
    let out = validate(manifest);
    assert!(
        out.status.success(),
        "{} is not a valid Kubernetes manifest (strict, versions {KUBERNETES_VERSIONS:?}):\n{}",
        manifest.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("k8s_job.py prints JSON")
}

/// Runs ribbon in `cwd`; panics with its stderr unless it exits 0.
fn ribbon(args: &[String], cwd: &Path) -> Output {
    let out = Command::new(common::ribbon_bin())
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap_or_else(|e| panic!("cannot run ribbon: {e}"));
    assert!(
        out.status.success(),
        "{} failed ({:?}):\n{}",
        common::shell_line(&common::ribbon_bin(), args),
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn s(path: &Path) -> String {
    path.to_str().expect("UTF-8 path").to_string()
}

/// The value after `flag` in a shell command line, split at spaces.
fn flag_value<'a>(line: &'a str, flag: &str) -> Option<&'a str> {
    let words: Vec<&str> = line.split_whitespace().collect();
    words
        .iter()
        .position(|w| *w == flag)
        .and_then(|i| words.get(i + 1).copied())
}

/// A pod's view of the files: its working directory (with `robots/`, as the image has it) and
/// the shared volume.
struct PodFiles {
    working_dir: PathBuf,
    volume: PathBuf,
    mount_path: String,
}

impl PodFiles {
    fn new(root: &Path, job: &JobDescription) -> Self {
        let _ = std::fs::remove_dir_all(root);
        let working_dir = root.join("image-work");
        let volume = root.join("volume");
        std::fs::create_dir_all(&working_dir).expect("mkdir working dir");
        std::fs::create_dir_all(&volume).expect("mkdir volume");
        std::os::unix::fs::symlink(common::manifest("robots"), working_dir.join("robots"))
            .expect("link robots/ into the pod's working directory");
        PodFiles {
            working_dir,
            volume,
            mount_path: job.mounts[0].mount_path.clone(),
        }
    }

    /// `path` under the mount as this test's directory (`/shared/x` → `<volume>/x`).
    fn on_volume(&self, text: &str) -> String {
        text.replace(
            &format!("{}/", self.mount_path),
            &format!("{}/", s(&self.volume)),
        )
    }

    /// Runs the Job's pods: `command` + `args` for each index, `parallelism` at a time, with a
    /// pod's environment. Panics naming the index of a pod that failed.
    fn run_job(&self, job: &JobDescription, ribbon_dir: &Path) {
        let completions = job.completions.expect("completions");
        let indices: Vec<usize> = (0..completions).collect();
        for wave in indices.chunks(job.parallelism.max(1)) {
            let pods: Vec<_> = wave
                .iter()
                .map(|&index| (index, self.spawn_pod(job, index, ribbon_dir)))
                .collect();
            for (index, pod) in pods {
                let out = pod.wait_with_output().expect("wait for a pod");
                assert!(
                    out.status.success(),
                    "pod {index} of job {} failed ({:?}):\n{}",
                    job.job,
                    out.status.code(),
                    String::from_utf8_lossy(&out.stderr)
                );
            }
        }
    }

    fn spawn_pod(
        &self,
        job: &JobDescription,
        index: usize,
        ribbon_dir: &Path,
    ) -> std::process::Child {
        let (program, rest) = job.command.split_first().expect("a command");
        let mut command = Command::new(program);
        command
            .args(rest.iter().map(|a| self.on_volume(a)))
            .args(job.args.iter().map(|a| self.on_volume(a)))
            .current_dir(&self.working_dir)
            .env_clear()
            .env("PATH", format!("{}:/usr/bin:/bin", s(ribbon_dir)))
            .env("JOB_COMPLETION_INDEX", index.to_string())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped());
        for var in &job.env {
            command.env(&var.name, self.on_volume(&var.value));
        }
        command
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start pod {index} ({program}): {e}"))
    }
}

/// The merge's outputs, on the volume.
fn merge_args(plan: &str, shards: &str, volume: &Path, tag: &str) -> Vec<String> {
    vec![
        "merge".into(),
        plan.into(),
        shards.into(),
        "--summary".into(),
        s(&volume.join(format!("{tag}.json"))),
        "--csv".into(),
        s(&volume.join(format!("{tag}.csv"))),
        "--out".into(),
        s(&volume.join(format!("{tag}.mcap"))),
    ]
}

fn assert_same_outputs(single: &Path, merged: &Path, what: &str) {
    for ext in ["csv", "mcap"] {
        let a = std::fs::read(single.with_extension(ext)).expect("single-machine output");
        let b = std::fs::read(merged.with_extension(ext)).expect("merged output");
        assert!(a == b, "{what}: the merged {ext} differs from analyze's");
    }
    assert_eq!(
        common::masked_summary_file(&single.with_extension("json")),
        common::masked_summary_file(&merged.with_extension("json")),
        "{what}: the merged summary differs from analyze's (timing fields masked)"
    );
}

#[test]
fn the_manifest_is_a_valid_indexed_job_that_ribbon_can_shard() {
    let job = describe(&common::manifest(MANIFEST));
    assert_eq!(
        job.completion_mode, "Indexed",
        "JOB_COMPLETION_INDEX needs an Indexed Job"
    );
    assert_eq!(
        job.restart_policy, "Never",
        "a Job's pods must not restart in place (a retry is a new pod)"
    );
    assert!(job.backoff_limit > 0, "a failed pod should be retried");
    let working_dir = job
        .working_dir
        .as_deref()
        .expect("workingDir: the plan's relative robot paths resolve there");
    let header = std::fs::read_to_string(common::manifest(MANIFEST)).expect("read manifest");
    assert!(
        header.contains(&format!("relative to {working_dir}")),
        "the manifest's header should say plan paths are relative to {working_dir}"
    );
    let completions = job.completions.expect("an Indexed Job needs completions");
    let line = job.args.join(" ");
    let shards: usize = flag_value(&line, "--shards")
        .unwrap_or_else(|| panic!("the pod command has no --shards: {line}"))
        .parse()
        .expect("--shards N");
    assert_eq!(
        shards, completions,
        "the command's --shards must equal the Job's completions"
    );
    assert!(line.contains("ribbon run "), "the pods run shards: {line}");
    assert_eq!(job.mounts.len(), 1, "one shared volume: {:?}", job.mounts);
    let mount = &job.mounts[0];
    let claim_name = mount
        .claim
        .as_deref()
        .unwrap_or_else(|| panic!("volume {} is not a PersistentVolumeClaim", mount.name));
    let claim = job
        .claims
        .iter()
        .find(|c| c.name == claim_name)
        .unwrap_or_else(|| panic!("claim {claim_name} is not declared in {MANIFEST}"));
    assert!(
        claim.access_modes.iter().any(|m| m == "ReadWriteMany"),
        "pods on several nodes write to the volume: it needs ReadWriteMany, has {:?}",
        claim.access_modes
    );
    for word in line.split_whitespace().filter(|w| w.starts_with('/')) {
        if word != "/bin/sh" {
            assert!(
                word.starts_with(&format!("{}/", mount.mount_path)),
                "{word} is not on the shared volume ({})",
                mount.mount_path
            );
        }
    }

    // The negative control: the validator refuses a misspelt field, so the check above can fail.
    let text = std::fs::read_to_string(common::manifest(MANIFEST)).expect("read manifest");
    assert!(text.contains("backoffLimit:"));
    let dir = common::target_dir().join("k8s-test");
    std::fs::create_dir_all(&dir).expect("mkdir");
    let misspelt = dir.join("misspelt.yaml");
    std::fs::write(&misspelt, text.replace("backoffLimit:", "backofLimit:")).expect("write");
    let out = validate(&misspelt);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("backofLimit"),
        "the validator accepted a misspelt field: {stderr}"
    );
}

#[test]
fn the_jobs_pods_give_the_single_machine_bytes_for_a_fixed_and_a_staged_study() {
    let job = describe(&common::manifest(MANIFEST));
    let ribbon_dir = common::ribbon_bin()
        .parent()
        .expect("the binary's directory")
        .to_path_buf();
    let line = job.args.join(" ");
    let plan_on_pod = flag_value(&line, "run")
        .expect("ribbon run PLAN")
        .to_string();
    let shards_on_pod = flag_value(&line, "--into").expect("--into DIR").to_string();
    let root = common::target_dir().join("k8s-test");

    // The manifest header's study (steps 1–4), and a screened design (two stages).
    let studies: [(&str, &[&str]); 2] = [
        ("fixed", &["robots/ur5/ur5.urdf", "--duration", "0.5"]),
        (
            "staged",
            &[
                "robots/ur5/ur5.urdf",
                "--duration",
                "0.2",
                "--method",
                "legendre-scan",
                "--design",
                "screened",
                "--order",
                "2",
            ],
        ),
    ];
    for (tag, study) in studies {
        let files = PodFiles::new(&root.join(tag), &job);
        let plan = files.on_volume(&plan_on_pod);
        let shards = files.on_volume(&shards_on_pod);
        let study: Vec<String> = study.iter().map(|a| a.to_string()).collect();

        let mut single = vec!["analyze".to_string()];
        single.extend(study.iter().cloned());
        for (flag, ext) in [("--summary", "json"), ("--csv", "csv"), ("--out", "mcap")] {
            single.extend([
                flag.to_string(),
                s(&files.volume.join(format!("single.{ext}"))),
            ]);
        }
        ribbon(&single, &files.working_dir);

        // Step 1: the plan, made where the image's files are (paths relative to workingDir).
        let mut args = vec!["plan".to_string()];
        args.extend(study.iter().cloned());
        args.extend(["--plan".to_string(), plan.clone()]);
        ribbon(&args, &files.working_dir);

        // Steps 2–4, as examples/k8s/README.md loops them: a Job per stage, then merge.
        let mut stages = 0;
        loop {
            stages += 1;
            assert!(
                stages <= 10,
                "{tag}: merge still plans stages after 10 Jobs"
            );
            files.run_job(&job, &ribbon_dir);
            if stages == 1 {
                // A retry of one pod (the Job's backoff): it rewrites only its own block.
                let completions = job.completions.expect("completions");
                let retried = files.spawn_pod(&job, completions - 1, &ribbon_dir);
                let out = retried.wait_with_output().expect("wait");
                assert!(out.status.success(), "{tag}: the retried pod failed");
            }
            let out = Command::new(common::ribbon_bin())
                .args(merge_args(&plan, &shards, &files.volume, "merged"))
                .current_dir(&files.working_dir)
                .output()
                .expect("run merge");
            match out.status.code() {
                Some(0) => break,
                Some(3) => continue,
                other => panic!(
                    "{tag}: merge exited {other:?}:\n{}",
                    String::from_utf8_lossy(&out.stderr)
                ),
            }
        }
        let expected_stages = if tag == "staged" { 2 } else { 1 };
        assert_eq!(
            stages, expected_stages,
            "{tag}: Jobs run before merge finished"
        );
        println!(
            "{tag}: {stages} Job(s) of {} pods, merged",
            job.completions.unwrap_or(0)
        );
        assert_same_outputs(
            &files.volume.join("single.json"),
            &files.volume.join("merged.json"),
            tag,
        );
    }
}
