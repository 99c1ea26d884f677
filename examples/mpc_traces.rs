//! Runs the MPC (without and with COTC) and the CWF on flight traces, closed loop and with
//! no limiter, and prints the leg margins, solver outcomes, step times and the RAE of the
//! perceived specific force against the aircraft's (docs/design.md §6). A check of the raw MPC, not
//! the engine's metrics: `cargo run --release --example mpc_traces -- ../shared/traces/*.csv`.

use std::time::Instant;

use hexcue_core::mca::mpc::{Mpc, Terminal};
use hexcue_core::mca::washout::Washout;
use hexcue_core::mca::{CueInput, CueSample, MotionCueing, PlatformCommand};
use hexcue_core::model::stewart::head_motion;
use hexcue_core::model::vestibular::Vestibular;
use hexcue_core::profile::text::default_profile;
use hexcue_core::G_MPS2;
use nalgebra::Vector3;

/// One algorithm step: the command and whether its QP (if any) was solved.
type StepFn = dyn FnMut(&CueInput) -> (PlatformCommand, bool);

fn read_trace(path: &str) -> Result<Vec<CueSample>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().ok_or("empty")?.split(',').collect();
    let col = |name: &str| header.iter().position(|h| h.trim() == name);
    let idx: Vec<usize> = ["fx", "fy", "fz", "p", "q", "r"]
        .iter()
        .map(|n| col(n).ok_or(format!("{path}: no column {n}")))
        .collect::<Result<_, _>>()?;
    let mut out = Vec::new();
    for line in lines.filter(|l| !l.trim().is_empty()) {
        let v: Vec<f64> = line
            .split(',')
            .map(|x| x.trim().parse().unwrap_or(0.0))
            .collect();
        let g = |i: usize| v.get(idx[i]).copied().unwrap_or(0.0);
        out.push(CueSample {
            delta_f_mps2: Vector3::new(g(0), g(1), g(2) + G_MPS2),
            angular_velocity_radps: Vector3::new(g(3), g(4), g(5)),
        });
    }
    Ok(out)
}

fn main() {
    let profile = default_profile();
    let stewart = profile.stewart();
    let dt = profile.dt_s();
    let f_lim = profile.input.specific_force_limit_mps2;
    let w_lim = profile.input.angular_velocity_limit_dps.to_radians();
    println!("trace              alg   RAE fx  RAE fy  min margin  beyond margin  failed  median/p99 step");
    for path in std::env::args().skip(1) {
        let samples = match read_trace(&path) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("{e}");
                continue;
            }
        };
        let samples: Vec<CueSample> = samples
            .iter()
            .map(|s| CueSample {
                delta_f_mps2: s.delta_f_mps2.map(|v| v.clamp(-f_lim, f_lim)),
                angular_velocity_radps: s.angular_velocity_radps.map(|v| v.clamp(-w_lim, w_lim)),
            })
            .collect();
        let name = std::path::Path::new(&path)
            .file_stem()
            .map_or(path.clone(), |s| s.to_string_lossy().into_owned());
        let mut reference = Vestibular::new(&profile.vestibular, dt);
        let refs: Vec<Vector3<f64>> = samples
            .iter()
            .map(|s| {
                reference
                    .step(&s.delta_f_mps2, &s.angular_velocity_radps)
                    .specific_force_mps2
            })
            .collect();
        let algs: Vec<(&str, Box<StepFn>)> = vec![
            ("mpc", {
                let mut m =
                    Mpc::new(&profile.mpc, &profile.setting(), Terminal::Free).expect("mpc");
                Box::new(move |i: &CueInput| {
                    let o = m.solve(i);
                    if !o.feasible && std::env::var("MPC_TRACE_STATUS").is_ok() {
                        eprintln!(
                            "k {} {} it {} {:.0} µs",
                            i.k, o.report.status, o.report.iterations, o.report.solve_time_us
                        );
                    }
                    (o.command, o.feasible)
                })
            }),
            ("cotc", {
                let mut m = Mpc::new(&profile.cotc_params(), &profile.setting(), Terminal::Cotc)
                    .expect("cotc");
                Box::new(move |i: &CueInput| {
                    let o = m.solve(i);
                    (o.command, o.feasible)
                })
            }),
            ("cwf", {
                let mut w = Washout::new(&profile.cwf, &profile.setting());
                Box::new(move |i: &CueInput| (w.step(i), true))
            }),
        ];
        for (alg, mut step) in algs {
            let mut perceived = Vestibular::new(&profile.vestibular, dt);
            let mut applied = PlatformCommand::default();
            let (mut err, mut sum) = ([0.0; 2], [0.0; 2]);
            let mut min_margin = f64::INFINITY;
            let (mut beyond, mut failed) = (0usize, 0usize);
            let mut times = Vec::with_capacity(samples.len());
            for (k, s) in samples.iter().enumerate() {
                let input = CueInput {
                    k,
                    t_s: k as f64 * dt,
                    dt_s: dt,
                    sample: *s,
                    preview: &samples[k + 1..],
                    applied: &applied,
                    deadline: None,
                };
                let t0 = Instant::now();
                let (c, ok) = step(&input);
                times.push(t0.elapsed().as_secs_f64() * 1e6);
                failed += usize::from(!ok);
                let m = stewart.margins(&stewart.leg_lengths(&c.pose)).min();
                min_margin = min_margin.min(m);
                beyond += usize::from(m < profile.limiter.leg_margin_m - 1e-3);
                let head = head_motion(&c.pose, &c.velocity, &c.acceleration, &profile.eye_point());
                let p = perceived.step(&head.delta_f_mps2, &head.angular_velocity_radps);
                for a in 0..2 {
                    err[a] += (p.specific_force_mps2[a] - refs[k][a]).abs();
                    sum[a] += refs[k][a].abs();
                }
                applied = c;
            }
            times.sort_by(f64::total_cmp);
            let pct = |q: f64| times[((times.len() - 1) as f64 * q) as usize];
            println!(
                "{name:<18} {alg:<5} {:>6.3}  {:>6.3}  {:>8.3} m  {:>6.2} %  {:>6}  {:>5.0}/{:.0} µs",
                err[0] / sum[0].max(1e-12),
                err[1] / sum[1].max(1e-12),
                min_margin,
                100.0 * beyond as f64 / samples.len() as f64,
                failed,
                pct(0.5),
                pct(0.99),
            );
        }
    }
}
