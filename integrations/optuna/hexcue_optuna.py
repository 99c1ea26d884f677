#!/usr/bin/env python3
"""A tuning campaign for hexcue on Optuna: any number of workers, on any number of machines,
sharing one Optuna storage (a journal file on a shared file system, or a database URL).

Every candidate is one `hexcue eval` process. What is searched (`hexcue eval --space`), how a
candidate is scored and whether it is feasible (`objective`, `feasible` of its result) and the
validation gate the result must pass (`verdict`) all come from the binary: this driver only
asks Optuna for candidates, hands them to `hexcue eval` and tells Optuna the objective. See
docs/tuning.md, "Campaigns on Optuna".

    hexcue_optuna.py create --storage study.log --study NAME --algorithm cwf \\
        --traces TRAINING --validate VALIDATION [--budget N] [--enqueue K]
    hexcue_optuna.py work   --storage study.log --study NAME      # as many as you like
    hexcue_optuna.py finish --storage study.log --study NAME --out TUNED.toml
    hexcue_optuna.py status --storage study.log --study NAME [--json]
    hexcue_optuna.py requeue --storage study.log --study NAME --running
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
import warnings

import optuna
from optuna.distributions import FloatDistribution
from optuna.trial import TrialState

CONFIG = "hexcue_config"
BASE = "hexcue_base"
NOT_COUNTED = "not_counted"


def storage_of(url: str):
    """A database URL (sqlite:///…, postgresql://…, mysql://…) as Optuna takes it; anything
    else is the path of a journal file, Optuna's storage for a shared file system."""
    if "://" in url:
        return url
    try:  # Optuna >= 4.0
        from optuna.storages.journal import JournalFileBackend, JournalStorage

        return JournalStorage(JournalFileBackend(url))
    except ImportError:  # Optuna 3.x
        from optuna.storages import JournalFileStorage, JournalStorage

        return JournalStorage(JournalFileStorage(url))


def hexcue(binary: str, args: list[str], threads: int | None = None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    if threads:
        env["RAYON_NUM_THREADS"] = str(threads)
    return subprocess.run(
        [binary, *args], capture_output=True, text=True, env=env, stdin=subprocess.DEVNULL
    )


def hexcue_json(binary: str, args: list[str], out: str, threads: int | None = None) -> dict:
    """Runs `hexcue ARGS --out OUT` and returns the JSON it wrote; exits on a failure with
    hexcue's own message, which names the bad file or key."""
    p = hexcue(binary, [*args, "--out", out, "--force"], threads)
    if p.returncode != 0:
        sys.exit(f"hexcue {' '.join(args)}: failed:\n{p.stderr.strip()}")
    with open(out) as f:
        return json.load(f)


def distributions(space: dict) -> dict[str, FloatDistribution]:
    return {
        k["name"]: FloatDistribution(k["lower"], k["upper"], log=k["log"]) for k in space["keys"]
    }


def set_args(params: dict[str, float]) -> list[str]:
    # repr: the shortest text that reads back as the same float, so the profile hexcue writes
    # is exactly the one Optuna was told about.
    out: list[str] = []
    for name, value in sorted(params.items()):
        out += ["--set", f"{name}={float(value)!r}"]
    return out


def eval_args(config: dict, base_file: str | None, validate: bool) -> list[str]:
    args = ["eval", "--algorithm", config["algorithm"], "--traces", ",".join(config["traces"])]
    if config.get("profile"):
        args += ["--profile", config["profile"]]
    if validate and config.get("validate"):
        args += ["--validate", ",".join(config["validate"])]
    if base_file:
        args += ["--base-result", base_file]
    return args


def load(args) -> tuple[optuna.Study, dict, dict]:
    study = optuna.load_study(study_name=args.study, storage=storage_of(args.storage))
    attrs = study.user_attrs
    if CONFIG not in attrs:
        sys.exit(f"{args.storage}: study `{args.study}` was not made by `hexcue_optuna.py create`")
    return study, attrs[CONFIG], attrs[BASE]


def counted(trials) -> list:
    """The trials that count toward the budget: all but those discarded (asked beyond the
    budget) or requeued (their candidate runs again in a new trial)."""
    return [t for t in trials if NOT_COUNTED not in t.user_attrs]


def cmd_create(args) -> None:
    binary = args.hexcue
    absolute = lambda paths: [os.path.abspath(p) for p in paths.split(",")]  # noqa: E731
    config = {
        "algorithm": args.algorithm,
        "profile": os.path.abspath(args.profile) if args.profile else None,
        "traces": absolute(args.traces),
        "validate": absolute(args.validate) if args.validate else [],
    }
    with tempfile.TemporaryDirectory() as tmp:
        space_args = ["eval", "--space", "--algorithm", args.algorithm]
        if config["profile"]:
            space_args += ["--profile", config["profile"]]
        space = hexcue_json(binary, space_args, os.path.join(tmp, "space.json"))
        # The base, once, on every flight (validation ones too): each worker and the final
        # gate compare with these figures through `--base-result`.
        base = hexcue_json(binary, eval_args(config, None, True), os.path.join(tmp, "base.json"))
    config.update(
        {
            "space": space,
            "budget": args.budget if args.budget is not None else space["default_budget"],
            "step": args.step if args.step is not None else space["default_step"],
            "sampler": args.sampler,
        }
    )
    study = optuna.create_study(
        study_name=args.study, storage=storage_of(args.storage), direction="minimize"
    )
    study.set_user_attr(CONFIG, config)
    study.set_user_attr(BASE, base)
    # The base is the first trial, as in `hexcue tune` (it counts toward the budget), when
    # its values lie within the space: CMA-ES then starts from it at once.
    base_trial = base_as_trial(config, base)
    if base_trial is not None:
        study.add_trial(base_trial)
    else:
        print("note: the base's values are not all within the space; it is not a trial")
    if args.enqueue:
        # A fixed set of candidates, drawn once here by the study's sampler (CMA-ES: a first
        # generation around the base; random: uniform), seeded: whichever worker runs which,
        # the study scores the same candidates, so its best does not depend on the number of
        # workers.
        draw = optuna.create_study(sampler=sampler_of(config, base, args.seed))
        if base_trial is not None:
            draw.add_trial(base_trial)
        for _ in range(args.enqueue):
            params = draw.ask(distributions(space)).params
            study.enqueue_trial(params, user_attrs={"drawn": f"{args.sampler}, seed {args.seed}"})
    print(
        f"study `{args.study}` in {args.storage}: {config['algorithm']} on "
        f"{len(config['traces'])} flights ({len(config['validate'])} for validation), "
        f"{len(space['keys'])} keys, budget {config['budget']} (the base included), "
        f"{args.enqueue or 0} enqueued; "
        f"base objective {base['objective']:.4f}"
    )


def base_as_trial(config: dict, base: dict):
    space = config["space"]
    values = {k["name"]: k["base"] for k in space["keys"]}
    if not all(k["lower"] <= k["base"] <= k["upper"] for k in space["keys"]):
        return None
    attrs = {"base": True, "mean_score": base["mean_score"], "feasible": base["feasible"]}
    return optuna.trial.create_trial(
        params=values, distributions=distributions(space), value=base["objective"], user_attrs=attrs
    )


def sampler_of(config: dict, base: dict, seed: int | None):
    space = config["space"]
    if config["sampler"] == "random":
        return optuna.samplers.RandomSampler(seed=seed)
    if config["sampler"] == "tpe":
        return optuna.samplers.TPESampler(seed=seed)
    # CMA-ES as `hexcue tune`: from the base's values, with its first step as a share of each
    # key's range (Optuna's CMA-ES works in [0, 1] coordinates, log keys on a log scale, as
    # tune does). x0 and sigma0 are deprecated since Optuna 4.9, still there in 5.0.
    x0 = {k["name"]: min(max(k["base"], k["lower"]), k["upper"]) for k in space["keys"]}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        return optuna.samplers.CmaEsSampler(x0=x0, sigma0=config["step"], seed=seed)


def evaluate(study, trial, config: dict, base_file: str, args, tmp: str) -> None:
    space = config["space"]
    params = {
        k["name"]: trial.suggest_float(k["name"], k["lower"], k["upper"], log=k["log"])
        for k in space["keys"]
    }
    worker = f"{socket.gethostname()}:{os.getpid()}"
    trial.set_user_attr("worker", worker)
    out = os.path.join(tmp, f"trial-{trial.number}.json")
    started = time.monotonic()
    p = hexcue(
        args.hexcue,
        [*eval_args(config, base_file, False), *set_args(params), "--out", out, "--force"],
        args.threads,
    )
    if p.returncode != 0:
        trial.set_user_attr("error", p.stderr.strip()[-2000:])
        study.tell(trial, state=TrialState.FAIL)
        print(f"trial {trial.number}: hexcue eval failed: {p.stderr.strip()}", file=sys.stderr)
        return
    with open(out) as f:
        r = json.load(f)
    for key in ("mean_score", "feasible", "profile_sha256", "wall_s"):
        trial.set_user_attr(key, r[key])
    study.tell(trial, r["objective"])
    print(
        f"trial {trial.number}: objective {r['objective']:.4f} (mean score "
        f"{r['mean_score']:.4f}{'' if r['feasible'] else ', infeasible'}) in "
        f"{time.monotonic() - started:.2f} s [{worker}]",
        file=sys.stderr,
    )


class Stopped(Exception):
    """SIGTERM: what Slurm sends at a time limit or a pre-emption, and `kill` by default."""


def on_sigterm(signum, frame):
    raise Stopped()


def hand_back(study, trial, space: dict) -> None:
    """A worker stopped mid-evaluation gives its candidate back: its trial fails and is not
    counted, and the same values are enqueued for the next worker."""
    params = dict(trial.params)
    try:
        trial.set_user_attr(NOT_COUNTED, "handed back: its worker was stopped")
        study.tell(trial, state=TrialState.FAIL)
    except Exception:  # stopped after its result was told: nothing to give back
        return
    if len(params) == len(space["keys"]):
        study.enqueue_trial(params, user_attrs={"requeued_from": trial.number})
    print(f"trial {trial.number}: stopped; its candidate is enqueued again", file=sys.stderr)


def cmd_work(args) -> None:
    study, config, base = load(args)
    study = optuna.load_study(
        study_name=args.study,
        storage=storage_of(args.storage),
        sampler=sampler_of(config, base, args.seed),
    )
    budget = config["budget"]
    signal.signal(signal.SIGTERM, on_sigterm)
    with tempfile.TemporaryDirectory() as tmp:
        base_file = os.path.join(tmp, "base.json")
        with open(base_file, "w") as f:
            json.dump(base, f)
        while True:
            trials = study.get_trials(deepcopy=False)
            waiting = any(t.state == TrialState.WAITING for t in trials)
            if not waiting and len(counted(trials)) >= budget:
                break
            trial = study.ask()
            frozen = {t.number: t for t in study.get_trials(deepcopy=False)}
            if "fixed_params" not in frozen[trial.number].system_attrs:
                # A new candidate, not one from the queue: it counts only within the budget.
                # Workers asking at once can pass the check above together; the trial numbers
                # decide which of them are beyond the budget.
                before = counted(t for n, t in frozen.items() if n < trial.number)
                if len(before) >= budget:
                    trial.set_user_attr(NOT_COUNTED, "asked beyond the budget")
                    study.tell(trial, state=TrialState.FAIL)
                    break
            try:
                evaluate(study, trial, config, base_file, args, tmp)
            except (KeyboardInterrupt, Stopped):
                hand_back(study, trial, config["space"])
                sys.exit(1)
            except optuna.exceptions.UpdateFinishedTrialError:
                # Two workers can pop the same queued trial from an SQLite database, which has
                # no row lock for Optuna's pop (optuna/optuna#4621): the other one finished it,
                # with the same candidate; this evaluation is dropped.
                print(f"trial {trial.number}: finished by another worker", file=sys.stderr)
                continue
            except BaseException:
                study.tell(trial, state=TrialState.FAIL)
                raise


def cmd_status(args) -> None:
    study, config, base = load(args)
    trials = study.get_trials(deepcopy=False)
    rows = [
        {
            "number": t.number,
            "state": t.state.name,
            "value": t.value,
            "params": t.params,
            "user_attrs": t.user_attrs,
        }
        for t in trials
    ]
    done = [t for t in counted(trials) if t.state == TrialState.COMPLETE]
    best = min(done, key=lambda t: (t.value, t.number), default=None)
    if args.json:
        print(
            json.dumps(
                {
                    "budget": config["budget"],
                    "base_objective": base["objective"],
                    "trials": rows,
                    "best": None if best is None else best.number,
                }
            )
        )
        return
    states: dict[str, int] = {}
    for t in counted(trials):
        states[t.state.name] = states.get(t.state.name, 0) + 1
    print(f"{len(counted(trials))} of {config['budget']} trials: {states}")
    print(f"base objective {base['objective']:.4f}")
    if best is not None:
        print(f"best: trial {best.number}, objective {best.value:.4f}")


def cmd_requeue(args) -> None:
    study, _, _ = load(args)
    trials = study.get_trials(deepcopy=False)
    chosen = [
        t
        for t in trials
        if t.state == TrialState.RUNNING
        and NOT_COUNTED not in t.user_attrs
        and (args.running or t.number in args.trial)
    ]
    missing = set(args.trial) - {t.number for t in chosen}
    if missing:
        sys.exit(f"requeue: trials {sorted(missing)} are not RUNNING; only a lost trial is requeued")
    for t in chosen:
        # Only once its worker is gone (killed, machine lost): a live worker would tell its
        # result to a trial already failed here.
        study._storage.set_trial_user_attr(t._trial_id, NOT_COUNTED, "requeued")
        study.tell(t.number, state=TrialState.FAIL)
        study.enqueue_trial(t.params, user_attrs={"requeued_from": t.number})
        print(f"trial {t.number}: failed and enqueued again")


def cmd_finish(args) -> None:
    study, config, base = load(args)
    trials = counted(study.get_trials(deepcopy=False))
    lost = [t.number for t in trials if t.state == TrialState.RUNNING]
    if lost:
        print(
            f"note: trials {lost} are still RUNNING: a worker is at them, or was lost with them "
            f"(`requeue --running` once no worker is)",
            file=sys.stderr,
        )
    done = sorted(
        (
            t
            for t in trials
            if t.state == TrialState.COMPLETE
            and t.user_attrs.get("feasible")
            and not t.user_attrs.get("base")
        ),
        key=lambda t: (t.value, t.number),
    )
    note = f"optuna study {args.study}, {len(trials)} trials"
    with tempfile.TemporaryDirectory() as tmp:
        base_file = os.path.join(tmp, "base.json")
        with open(base_file, "w") as f:
            json.dump(base, f)
        chosen = None
        if config["validate"]:
            # As `hexcue tune --validate`: the best training candidates go through the gate
            # (`verdict`), and the accepted one with the lowest validation mean is the result;
            # ties go to the earlier trial.
            judged = []
            for t in done[: args.validate_best]:
                out = os.path.join(tmp, f"gate-{t.number}.json")
                r = hexcue_json(
                    args.hexcue,
                    [
                        *eval_args(config, base_file, True),
                        *set_args(t.params),
                        "--save-profile",
                        os.path.join(tmp, f"trial-{t.number}.toml"),
                        "--note",
                        f"{note}, trial {t.number}",
                    ],
                    out,
                )
                verdict = r["verdict"]
                print(
                    f"trial {t.number}: objective {t.value:.4f}, validation mean "
                    f"{r['validation']['mean_score']:.4f} (base "
                    f"{r['validation']['base_mean_score']:.4f}): "
                    + ("accepted" if verdict["accepted"] else f"not accepted: {verdict['reason']}")
                )
                if verdict["accepted"]:
                    judged.append((r["validation"]["mean_score"], t.number))
            if judged:
                chosen = min(judged)[1]
        elif done and done[0].value < base["objective"]:
            # As `hexcue tune` without --validate: the best feasible candidate, if it beats the
            # base.
            chosen = done[0].number
            hexcue_json(
                args.hexcue,
                [
                    *eval_args(config, base_file, False),
                    *set_args(done[0].params),
                    "--save-profile",
                    os.path.join(tmp, f"trial-{chosen}.toml"),
                    "--note",
                    f"{note}, trial {chosen}",
                ],
                os.path.join(tmp, "best.json"),
            )
        if chosen is None:
            hexcue_json(
                args.hexcue,
                [
                    *eval_args(config, None, True),
                    "--save-profile",
                    os.path.join(tmp, "base.toml"),
                    "--note",
                    f"{note}: base kept, no candidate passed tune's gate",
                ],
                os.path.join(tmp, "kept.json"),
            )
            written = os.path.join(tmp, "base.toml")
        else:
            written = os.path.join(tmp, f"trial-{chosen}.toml")
        if os.path.exists(args.out) and not args.force:
            sys.exit(f"{args.out}: --out: the file exists; pass --force to overwrite it")
        with open(written) as src, open(args.out, "w") as dst:
            dst.write(src.read())
    print(
        f"wrote {args.out}: "
        + (f"trial {chosen}" if chosen is not None else "the base (no candidate accepted)")
    )


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)

    def common(q):
        q.add_argument("--storage", required=True, help="journal file, or a database URL")
        q.add_argument("--study", required=True, help="the study's name")
        q.add_argument("--hexcue", default="hexcue", help="the hexcue binary (default: on PATH)")

    c = sub.add_parser("create", help="a new study: the space, the base, the budget")
    common(c)
    c.add_argument("--algorithm", required=True, choices=["cwf", "mpc", "smpc"])
    c.add_argument("--profile", help="base profile (default: hexcue's embedded full-flight)")
    c.add_argument("--traces", required=True, help="training flights: files or folders, comma-separated")
    c.add_argument("--validate", help="validation flights: files or folders, comma-separated")
    c.add_argument("--budget", type=int, help="candidates to score (default: tune's)")
    c.add_argument("--step", type=float, help="CMA-ES's first step, a share of each key's range")
    c.add_argument("--sampler", choices=["cmaes", "tpe", "random"], default="cmaes")
    c.add_argument("--enqueue", type=int, default=0, help="draw this many candidates now (random, --seed)")
    c.add_argument("--seed", type=int, default=1, help="seed of --enqueue's draw")

    w = sub.add_parser("work", help="a worker: ask, `hexcue eval`, tell, until the budget is spent")
    common(w)
    w.add_argument("--seed", type=int, help="the sampler's seed (only a lone worker is reproducible)")
    w.add_argument("--threads", type=int, help="threads per `hexcue eval` (RAYON_NUM_THREADS)")

    s = sub.add_parser("status", help="the trials so far")
    common(s)
    s.add_argument("--json", action="store_true")

    r = sub.add_parser("requeue", help="run a lost trial's candidate again (its worker is gone)")
    common(r)
    r.add_argument("--trial", type=int, action="append", default=[])
    r.add_argument("--running", action="store_true", help="every RUNNING trial")

    f = sub.add_parser("finish", help="the best candidates through tune's gate; the profile")
    common(f)
    f.add_argument("--out", required=True, help="the tuned profile to write")
    f.add_argument("--validate-best", type=int, default=5, help="how many of the best to validate")
    f.add_argument("--force", action="store_true")

    args = p.parse_args(argv)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    {
        "create": cmd_create,
        "work": cmd_work,
        "status": cmd_status,
        "requeue": cmd_requeue,
        "finish": cmd_finish,
    }[args.command](args)


if __name__ == "__main__":
    main()
