//! A real single-node Slurm on loopback runs a sharded study (issue 14): `slurmctld` and `slurmd`
//! started here without systemd (`auth/none`, a configuration under `target/`), the shipped
//! `examples/slurm/shard.sbatch` submitted as a 4-task array with `sbatch --wait`, the shards
//! merged, and the outputs compared byte for byte with a single-machine `analyze`; then a staged
//! study (a screened design, two stages) through `examples/slurm/stages.sh`, the same way.
//!
//! When Slurm is absent the test installs Debian's `slurm-wlm` (`apt-get install -y slurm-wlm`,
//! as root) on CI (`CI` set) or when the person running it opted in (`RIBBON_TEST_INSTALL=1`);
//! otherwise, or when it cannot, it fails with the command to run. It never skips.

mod common;

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// How long the daemons may take to bring the node up.
const NODE_UP_TIMEOUT: Duration = Duration::from_secs(60);
/// Shards of the study (array tasks).
const SHARDS: usize = 4;

fn manifest() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn run(command: &mut Command, what: &str) -> Output {
    let out = command
        .output()
        .unwrap_or_else(|e| panic!("{what}: cannot start {command:?}: {e}"));
    assert!(
        out.status.success(),
        "{what} failed ({:?}): {command:?}\nstdout: {}\nstderr: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Installs `slurm-wlm` when `slurmctld`, `slurmd`, `sbatch` or `sinfo` is missing — on CI or when
/// the person running the tests opted in (`RIBBON_TEST_INSTALL=1`); otherwise fails naming the
/// command ([`common::ensure_system_programs`]).
fn ensure_slurm() {
    common::ensure_system_programs(
        "slurm",
        &["slurmctld", "slurmd", "sbatch", "sinfo"],
        &["slurm-wlm"],
    );
}

/// A free TCP port on loopback (bound, then released).
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port on loopback")
}

/// The daemons, stopped (by their process ids) when dropped.
struct Daemons(Vec<Child>);

impl Drop for Daemons {
    fn drop(&mut self) {
        for child in &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

fn start_cluster(dir: &Path) -> (PathBuf, Daemons) {
    let _ = std::fs::remove_dir_all(dir);
    for sub in ["state", "spool"] {
        std::fs::create_dir_all(dir.join(sub)).expect("create the Slurm directories");
    }
    let host = String::from_utf8(run(Command::new("hostname").arg("-s"), "hostname -s").stdout)
        .expect("hostname")
        .trim()
        .to_string();
    let (ctld_port, d_port) = (free_port(), free_port());
    let d = dir.display();
    let config = format!(
        "ClusterName=ribbontest\n\
         SlurmctldHost={host}(127.0.0.1)\n\
         SlurmctldPort={ctld_port}\n\
         SlurmdPort={d_port}\n\
         AuthType=auth/none\n\
         CredType=cred/none\n\
         SlurmUser=root\n\
         SlurmdUser=root\n\
         StateSaveLocation={d}/state\n\
         SlurmdSpoolDir={d}/spool\n\
         SlurmctldPidFile={d}/slurmctld.pid\n\
         SlurmdPidFile={d}/slurmd.pid\n\
         SlurmctldLogFile={d}/slurmctld.log\n\
         SlurmdLogFile={d}/slurmd.log\n\
         ProctrackType=proctrack/pgid\n\
         TaskPlugin=task/none\n\
         SwitchType=switch/none\n\
         JobAcctGatherType=jobacct_gather/none\n\
         AccountingStorageType=accounting_storage/none\n\
         SchedulerType=sched/backfill\n\
         SelectType=select/cons_tres\n\
         SelectTypeParameters=CR_Core\n\
         ReturnToService=2\n\
         MpiDefault=none\n\
         NodeName=ribbonnode NodeAddr=127.0.0.1 CPUs=2 RealMemory=1000 State=UNKNOWN\n\
         PartitionName=ribbon Nodes=ribbonnode Default=YES MaxTime=INFINITE State=UP\n"
    );
    let conf = dir.join("slurm.conf");
    std::fs::write(&conf, config).expect("write slurm.conf");
    let spawn = |program: &str, args: &[&str]| {
        Command::new(program)
            .args(args)
            .env("SLURM_CONF", &conf)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {program}: {e}"))
    };
    let conf_text = conf.to_str().expect("UTF-8 path");
    let mut daemons = Daemons(Vec::new());
    daemons
        .0
        .push(spawn("slurmctld", &["-D", "-i", "-f", conf_text]));
    std::thread::sleep(Duration::from_secs(1));
    daemons.0.push(spawn(
        "slurmd",
        &["-D", "-N", "ribbonnode", "-f", conf_text],
    ));
    let started = Instant::now();
    loop {
        let state = Command::new("sinfo")
            .args(["-h", "-o", "%t"])
            .env("SLURM_CONF", &conf)
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
            .unwrap_or_default();
        if state == "idle" {
            break;
        }
        assert!(
            started.elapsed() < NODE_UP_TIMEOUT,
            "the Slurm node did not come up within {NODE_UP_TIMEOUT:?} (sinfo says '{state}'); logs: {d}/slurmctld.log, {d}/slurmd.log"
        );
        std::thread::sleep(Duration::from_millis(500));
    }
    (conf, daemons)
}

fn ribbon(args: &[&str]) -> Output {
    run(
        Command::new(env!("CARGO_BIN_EXE_ribbon"))
            .current_dir(manifest())
            .args(args),
        "ribbon",
    )
}

#[test]
fn a_slurm_array_runs_the_shards_and_the_merge_matches_analyze() {
    ensure_slurm();
    let dir = manifest().join("target/slurm-test");
    let (conf, _daemons) = start_cluster(&dir.join("cluster"));
    let work = dir.join("study");
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work).expect("mkdir");
    let s = |p: &Path| p.to_str().expect("UTF-8 path").to_string();
    let study = ["robots/four_bar/four_bar.urdf", "--duration", "0.5"];
    let outputs = |tag: &str| {
        vec![
            "--summary".to_string(),
            s(&work.join(format!("{tag}.json"))),
            "--csv".to_string(),
            s(&work.join(format!("{tag}.csv"))),
            "--out".to_string(),
            s(&work.join(format!("{tag}.mcap"))),
        ]
    };
    let mut args: Vec<String> = vec!["analyze".into()];
    args.extend(study.iter().map(|a| a.to_string()));
    args.extend(outputs("single"));
    ribbon(&args.iter().map(String::as_str).collect::<Vec<_>>());

    let plan = work.join("study.plan");
    let mut args: Vec<String> = vec!["plan".into()];
    args.extend(study.iter().map(|a| a.to_string()));
    args.extend(["--plan".to_string(), s(&plan)]);
    let line = ribbon(&args.iter().map(String::as_str).collect::<Vec<_>>()).stdout;
    println!("{}", String::from_utf8_lossy(&line));

    let shards = work.join("shards");
    let submitted = Instant::now();
    run(
        Command::new("sbatch")
            .current_dir(manifest())
            .args([
                "--wait",
                &format!("--array=0-{}", SHARDS - 1),
                &format!("--output={}/slurm-%A_%a.out", s(&work)),
                "examples/slurm/shard.sbatch",
            ])
            .env("SLURM_CONF", &conf)
            .env("RIBBON", env!("CARGO_BIN_EXE_ribbon"))
            .env("PLAN", &plan)
            .env("SHARDS", &shards),
        "sbatch --wait (task logs in target/slurm-test/study/slurm-*.out)",
    );
    let array_seconds = submitted.elapsed().as_secs_f64();
    println!(
        "the {SHARDS}-task Slurm array took {array_seconds:.1} s (submission to --wait's return)"
    );
    for k in 0..SHARDS {
        let file = shards.join(format!("shard-{k}-of-{SHARDS}.records.mcap"));
        assert!(file.exists(), "array task {k} wrote no {}", file.display());
    }

    let mut args: Vec<String> = vec!["merge".into(), s(&plan), s(&shards)];
    args.extend(outputs("merged"));
    ribbon(&args.iter().map(String::as_str).collect::<Vec<_>>());
    for ext in ["csv", "mcap"] {
        let single = std::fs::read(work.join(format!("single.{ext}"))).expect("single");
        let merged = std::fs::read(work.join(format!("merged.{ext}"))).expect("merged");
        assert!(single == merged, "the merged {ext} differs from analyze's");
    }
    assert_eq!(
        common::masked_summary_file(&work.join("single.json")),
        common::masked_summary_file(&work.join("merged.json")),
        "the merged summary differs from analyze's (timing fields masked)"
    );

    // A staged study (a screened design: the screening, then the design built on its ranking)
    // through examples/slurm/stages.sh: one array per stage, merge after each, until merge
    // exits 0.
    let staged = [
        "robots/ur5/ur5.urdf",
        "--duration",
        "0.2",
        "--method",
        "legendre-scan",
        "--design",
        "screened",
        "--order",
        "2",
    ];
    let mut args: Vec<String> = vec!["analyze".into()];
    args.extend(staged.iter().map(|a| a.to_string()));
    args.extend(outputs("staged-single"));
    ribbon(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let staged_plan = work.join("staged.plan");
    let mut args: Vec<String> = vec!["plan".into()];
    args.extend(staged.iter().map(|a| a.to_string()));
    args.extend(["--plan".to_string(), s(&staged_plan)]);
    ribbon(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let submitted = Instant::now();
    let driver = run(
        Command::new("sh")
            .current_dir(manifest())
            .args(["examples/slurm/stages.sh", "2"])
            .env("SLURM_CONF", &conf)
            .env("RIBBON", env!("CARGO_BIN_EXE_ribbon"))
            .env("PLAN", &staged_plan)
            .env("SHARDS", work.join("staged-shards"))
            .env("SUMMARY", work.join("staged-merged.json"))
            .env("CSV", work.join("staged-merged.csv"))
            .env("MCAP", work.join("staged-merged.mcap"))
            .env(
                "SBATCH_FLAGS",
                format!("--output={}/slurm-staged-%A_%a.out", s(&work)),
            ),
        "examples/slurm/stages.sh (task logs in target/slurm-test/study/slurm-staged-*.out)",
    );
    let stderr = String::from_utf8_lossy(&driver.stderr);
    assert!(stderr.contains("done after 2 stages"), "{stderr}");
    println!(
        "the two-stage study (2 arrays of 2 tasks and 2 merges) took {:.1} s",
        submitted.elapsed().as_secs_f64()
    );
    for ext in ["csv", "mcap"] {
        let single = std::fs::read(work.join(format!("staged-single.{ext}"))).expect("single");
        let merged = std::fs::read(work.join(format!("staged-merged.{ext}"))).expect("merged");
        assert!(single == merged, "the staged {ext} differs from analyze's");
    }
    assert_eq!(
        common::masked_summary_file(&work.join("staged-single.json")),
        common::masked_summary_file(&work.join("staged-merged.json")),
        "the staged summary differs from analyze's (timing fields masked)"
    );
}
