//! The Optuna campaign (integrations/optuna/hexcue_optuna.py, docs/tuning.md "Campaigns on
//! Optuna") with real Optuna on a journal file and `hexcue eval` workers. Python packages go
//! in a venv under target/ made here; the tests are skipped, saying why, only when pip cannot
//! install Optuna.
//!
//! "The same best" with parallel ask/tell: a sampler's next candidate depends on which results
//! it has been told, so two workers do not ask what one would. The studies here are a fixed
//! set of candidates drawn at creation (the base and a seeded first CMA-ES generation around
//! it, enqueued), so that one worker and two score the same candidates in whatever order, and
//! the same best is a claim about the storage, the workers and the evaluations: nothing lost,
//! nothing scored twice, every score the same.

mod common;

use std::collections::BTreeMap;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use common::{python_venv, repo, stderr};
use serde_json::Value;

/// The venv's Python with Optuna, made once per test run: the tests run in parallel and must
/// not both create the venv.
fn optuna_python() -> Option<PathBuf> {
    static PYTHON: OnceLock<Option<PathBuf>> = OnceLock::new();
    PYTHON
        .get_or_init(|| python_venv("optuna-venv", &["optuna", "cmaes"], "import optuna, cmaes"))
        .clone()
}

struct Campaign {
    python: PathBuf,
    storage: PathBuf,
}

impl Campaign {
    fn new(python: &Path, dir: &Path, name: &str) -> Self {
        Campaign {
            python: python.to_path_buf(),
            storage: dir.join(format!("{name}.log")),
        }
    }

    /// A study on a database storage: an SQLite file, through the URL Optuna's
    /// `RDBStorage` takes (SQLAlchemy comes with Optuna), as a PostgreSQL or MySQL URL
    /// would be given on a cluster.
    fn on_database(python: &Path, dir: &Path, name: &str) -> Self {
        Campaign {
            python: python.to_path_buf(),
            storage: format!("sqlite:///{}", dir.join(format!("{name}.db")).display()).into(),
        }
    }

    /// `work` in `n` worker processes at once, each checked to end well.
    fn work_in_parallel(&self, n: usize) {
        let workers: Vec<_> = (0..n)
            .map(|_| {
                self.command("work", env!("CARGO_BIN_EXE_hexcue"), &[])
                    .stdout(Stdio::piped())
                    .stderr(Stdio::piped())
                    .spawn()
                    .unwrap()
            })
            .collect();
        for w in workers {
            let out = w.wait_with_output().unwrap();
            assert!(out.status.success(), "worker: {}", stderr(&out));
        }
    }

    fn command(&self, sub: &str, hexcue: &str, extra: &[&str]) -> Command {
        let mut c = Command::new(&self.python);
        c.arg(repo().join("integrations/optuna/hexcue_optuna.py"))
            .arg(sub)
            .arg("--storage")
            .arg(&self.storage)
            .args(["--study", "campaign", "--hexcue", hexcue])
            .args(extra)
            .current_dir(repo())
            .stdin(Stdio::null());
        c
    }

    fn run(&self, sub: &str, extra: &[&str]) -> Output {
        let out = self
            .command(sub, env!("CARGO_BIN_EXE_hexcue"), extra)
            .output()
            .unwrap();
        assert!(out.status.success(), "{sub}: {}", stderr(&out));
        out
    }

    /// The study of the tests: the take-off and the stall for training, the landing for
    /// validation, the CWF (fast), the base and 8 candidates.
    fn create(&self) {
        self.run(
            "create",
            &[
                "--algorithm",
                "cwf",
                "--traces",
                "recordings/traces/takeoff.csv,recordings/traces/horizontal-stall.csv",
                "--validate",
                "recordings/traces/landing.csv",
                "--budget",
                "9",
                "--enqueue",
                "8",
                "--seed",
                "3",
            ],
        );
    }

    fn status(&self) -> Value {
        let out = self.run("status", &["--json"]);
        serde_json::from_slice(&out.stdout).unwrap()
    }
}

/// The trials that count (not discarded beyond the budget, not requeued), by number.
fn counted(status: &Value) -> Vec<&Value> {
    status["trials"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| t["user_attrs"].get("not_counted").is_none())
        .collect()
}

/// Each completed candidate's objective, by its values.
fn scores(status: &Value) -> BTreeMap<String, f64> {
    counted(status)
        .iter()
        .filter(|t| t["state"] == "COMPLETE")
        .map(|t| (t["params"].to_string(), t["value"].as_f64().unwrap()))
        .collect()
}

/// The best candidate: (its values, its objective).
fn best(scores: &BTreeMap<String, f64>) -> (String, f64) {
    scores
        .iter()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map(|(p, v)| (p.clone(), *v))
        .unwrap()
}

/// A worker whose evaluation never ends: a stand-in for `hexcue` that says it started and
/// then does not finish. Returns once it has started, so that the worker is stopped while its
/// candidate is being evaluated. In its own process group, to be killed with its evaluation.
fn hanging_worker(study: &Campaign, dir: &Path) -> std::process::Child {
    let started = dir.join("started");
    let stand_in = dir.join("hanging-hexcue");
    std::fs::write(
        &stand_in,
        format!(
            "#!/bin/sh\ntouch '{}'\nexec sleep 3600\n",
            started.display()
        ),
    )
    .unwrap();
    std::fs::set_permissions(
        &stand_in,
        std::os::unix::fs::PermissionsExt::from_mode(0o755),
    )
    .unwrap();
    let mut worker = study
        .command("work", &stand_in.display().to_string(), &[])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .process_group(0)
        .spawn()
        .unwrap();
    let limit = Instant::now() + Duration::from_secs(120);
    while !started.exists() {
        assert!(
            Instant::now() < limit,
            "the worker never started an evaluation"
        );
        if let Some(s) = worker.try_wait().unwrap() {
            panic!("the worker ended before its evaluation: {s}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    worker
}

/// The reference: one worker through the whole study.
fn one_worker(python: &Path, dir: &Path) -> (Campaign, Value, Duration) {
    let one = Campaign::new(python, dir, "one");
    one.create();
    let started = Instant::now();
    one.run("work", &[]);
    let wall = started.elapsed();
    let status = one.status();
    (one, status, wall)
}

#[test]
fn two_workers_on_one_journal_find_the_same_best_as_one_worker() {
    let Some(python) = optuna_python() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (one, reference, one_wall) = one_worker(&python, dir.path());

    let two = Campaign::new(&python, dir.path(), "two");
    two.create();
    let started = Instant::now();
    two.work_in_parallel(2);
    let two_wall = started.elapsed();
    let status = two.status();

    // Every candidate of the study scored once, with the score one worker gave it.
    for s in [&reference, &status] {
        let c = counted(s);
        assert_eq!(c.len(), 9, "{s}");
        assert!(c.iter().all(|t| t["state"] == "COMPLETE"), "{s}");
    }
    let (a, b) = (scores(&reference), scores(&status));
    assert_eq!(a.len(), 9, "nine different candidates");
    assert_eq!(a, b);
    assert_eq!(best(&a), best(&b));
    let by_worker: BTreeMap<String, usize> = counted(&status)
        .iter()
        .filter_map(|t| t["user_attrs"]["worker"].as_str())
        .fold(BTreeMap::new(), |mut m, w| {
            *m.entry(w.to_string()).or_default() += 1;
            m
        });
    eprintln!(
        "one worker: {:.2} s; two workers: {:.2} s, trials per worker {by_worker:?}",
        one_wall.as_secs_f64(),
        two_wall.as_secs_f64()
    );

    // The result through tune's gate: the same profile from either study.
    let (p1, p2) = (dir.path().join("one.toml"), dir.path().join("two.toml"));
    one.run("finish", &["--out", &p1.display().to_string()]);
    let out = two.run("finish", &["--out", &p2.display().to_string()]);
    let (t1, t2) = (
        std::fs::read_to_string(&p1).unwrap(),
        std::fs::read_to_string(&p2).unwrap(),
    );
    assert_eq!(t1, t2);
    let said = common::stdout(&out);
    let chosen: u64 = said
        .lines()
        .last()
        .and_then(|l| l.split("trial ").nth(1))
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("finish chose no trial (this study has accepted ones):\n{said}"));
    assert!(
        t1.starts_with("# tuned: `hexcue eval --algorithm cwf --set "),
        "{t1}"
    );
    assert!(t1
        .lines()
        .next()
        .unwrap()
        .contains(&format!("trial {chosen}")));

    // The written profile holds the chosen trial's values, keeps the base's comments, and
    // passes tune's gate: checked here from its figures, against the base.
    let trial = &status["trials"][chosen as usize];
    let space = common::hexcue(&[
        "eval",
        "--space",
        "--algorithm",
        "cwf",
        "--profile",
        &p2.display().to_string(),
    ]);
    assert!(space.status.success(), "{}", stderr(&space));
    let space: Value = serde_json::from_slice(&space.stdout).unwrap();
    for k in space["keys"].as_array().unwrap() {
        let name = k["name"].as_str().unwrap();
        assert_eq!(k["base"].as_f64(), trial["params"][name].as_f64(), "{name}");
    }
    let shipped = std::fs::read_to_string(repo().join("profiles/full-flight.toml")).unwrap();
    for line in shipped.lines().filter(|l| l.trim_start().starts_with('#')) {
        assert!(t2.contains(line), "comment lost: {line}");
    }
    let r = dir.path().join("judged.json");
    let o = common::hexcue(&[
        "eval",
        "--algorithm",
        "cwf",
        "--traces",
        "recordings/traces/takeoff.csv,recordings/traces/horizontal-stall.csv",
        "--validate",
        "recordings/traces/landing.csv",
        "--out",
        &r.display().to_string(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let base = common::read_json(&r);
    let o = common::hexcue(&[
        "eval",
        "--algorithm",
        "cwf",
        "--profile",
        &p2.display().to_string(),
        "--traces",
        "recordings/traces/takeoff.csv,recordings/traces/horizontal-stall.csv",
        "--validate",
        "recordings/traces/landing.csv",
        "--out",
        &dir.path().join("tuned.json").display().to_string(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let tuned = common::read_json(&dir.path().join("tuned.json"));
    let flights = |r: &Value| -> Vec<Value> {
        let mut v = r["flights"].as_array().unwrap().clone();
        v.extend(r["validation"]["flights"].as_array().unwrap().clone());
        v
    };
    for (t, b) in flights(&tuned).iter().zip(flights(&base)) {
        assert_eq!(t["name"], b["name"]);
        assert!(
            t["score"].as_f64().unwrap() <= 1.02 * b["score"].as_f64().unwrap(),
            "{}",
            t["name"]
        );
        assert_eq!(t["leg_violations"], 0);
        assert!(
            t["limiter_fraction"].as_f64().unwrap()
                <= b["limiter_fraction"].as_f64().unwrap() + 0.001
        );
    }
    assert!(
        tuned["validation"]["mean_score"].as_f64().unwrap()
            < base["validation"]["mean_score"].as_f64().unwrap()
    );
}

/// The same study on a database storage (the storage a cluster without a shared file system
/// uses): two workers on one SQLite URL score the same candidates as one worker on a journal.
#[test]
fn two_workers_on_a_database_find_the_same_best_as_one_on_a_journal() {
    let Some(python) = optuna_python() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (_, reference, _) = one_worker(&python, dir.path());
    let db = Campaign::on_database(&python, dir.path(), "db");
    db.create();
    db.work_in_parallel(2);
    let status = db.status();
    let c = counted(&status);
    assert_eq!(c.len(), 9, "{status}");
    assert!(c.iter().all(|t| t["state"] == "COMPLETE"), "{status}");
    assert_eq!(scores(&reference), scores(&status));
    assert_eq!(best(&scores(&reference)), best(&scores(&status)));
}

#[test]
fn a_worker_killed_mid_study_loses_nothing_but_its_own_candidate() {
    let Some(python) = optuna_python() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (_, reference, _) = one_worker(&python, dir.path());
    let all = scores(&reference);

    let study = Campaign::new(&python, dir.path(), "killed");
    study.create();
    let mut doomed = hanging_worker(&study, dir.path());
    // The worker and its evaluation, as a lost machine would lose them.
    let rc = unsafe { libc::kill(-(doomed.id() as libc::pid_t), libc::SIGKILL) };
    assert_eq!(rc, 0);
    doomed.wait().unwrap();

    study.run("work", &[]);
    let status = study.status();
    let c = counted(&status);
    assert_eq!(c.len(), 9, "{status}");
    let lost: Vec<&&Value> = c.iter().filter(|t| t["state"] == "RUNNING").collect();
    assert_eq!(lost.len(), 1, "{status}");
    assert_eq!(
        c.iter().filter(|t| t["state"] == "COMPLETE").count(),
        8,
        "{status}"
    );
    let lost_params = lost[0]["params"].to_string();
    // Every other candidate scored, as the reference scored it; the best of those.
    let mut others = all.clone();
    others
        .remove(&lost_params)
        .expect("the lost trial is one of the study's candidates");
    let now = scores(&status);
    assert_eq!(now, others);
    assert_eq!(best(&now), best(&others));

    // Its candidate requeued, once no worker is at it: the study is the reference's.
    study.run("requeue", &["--running"]);
    study.run("work", &[]);
    let status = study.status();
    let c = counted(&status);
    assert_eq!(c.len(), 9, "{status}");
    assert!(c.iter().all(|t| t["state"] == "COMPLETE"), "{status}");
    assert_eq!(scores(&status), all);
    assert_eq!(best(&scores(&status)), best(&all));
}

#[test]
fn a_worker_stopped_by_sigterm_hands_its_candidate_back() {
    let Some(python) = optuna_python() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (_, reference, _) = one_worker(&python, dir.path());
    let study = Campaign::new(&python, dir.path(), "stopped");
    study.create();
    let worker = hanging_worker(&study, dir.path());
    // SIGTERM to the worker alone, as Slurm sends at a time limit or a pre-emption.
    let rc = unsafe { libc::kill(worker.id() as libc::pid_t, libc::SIGTERM) };
    assert_eq!(rc, 0);
    let out = worker.wait_with_output().unwrap();
    let err = stderr(&out);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("its candidate is enqueued again"), "{err}");
    let status = study.status();
    let trials = status["trials"].as_array().unwrap();
    let handed: Vec<&Value> = trials
        .iter()
        .filter(|t| t["user_attrs"].get("not_counted").is_some())
        .collect();
    assert_eq!(handed.len(), 1, "{status}");
    assert_eq!(handed[0]["state"], "FAIL");
    let again = trials
        .iter()
        .find(|t| t["user_attrs"]["requeued_from"] == handed[0]["number"])
        .unwrap_or_else(|| panic!("not enqueued again: {status}"));
    assert_eq!(again["state"], "WAITING");
    // The next worker scores it with the others: the study is the reference's.
    study.run("work", &[]);
    let status = study.status();
    let c = counted(&status);
    assert_eq!(c.len(), 9, "{status}");
    assert!(c.iter().all(|t| t["state"] == "COMPLETE"), "{status}");
    assert_eq!(scores(&status), scores(&reference));
}
