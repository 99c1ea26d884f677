//! A profile's `[ground]` followed live from FlightGear and X-Plane (issue 36, docs/live.md
//! *Air and ground*), in this process against stand-ins that send as the simulators do:
//!
//! - FlightGear: datagrams built from the shipped protocol file
//!   (integrations/flightgear/hexcue.xml) the way FlightGear's generic protocol writes them
//!   (tests/common/flightgear.rs), from property values in FlightGear's units: the gears'
//!   `wow`, `altitude-agl-ft`, `groundspeed-kt`; and from the same file without its `wow`
//!   chunks (an FDM that sets no gear), where height and speed decide with the profile's
//!   `[ground_detection]` thresholds.
//! - X-Plane: a fake that answers the session's RREF subscriptions (tests/common/xplane.rs),
//!   `onground_any`, `y_agl` and `groundspeed` among them.
//!
//! Each stand-in writes its simulator time into the heading (10° + 1° a second), so that
//! each step tells which sample it used. The session's phase at every step must be what the
//! core's `GroundDetector`, with the profile's thresholds, decides from what that sample
//! said (the steps with fresh input only, as the session decides); and the changes must be
//! the script's, with their events and the summary's lines.

mod common;

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::flightgear::{datagram, protocol_file, Protocol};
use common::xplane::FakeXPlane;
use common::*;
use hexcue::live::{run, Control, LaneOrders, LiveSession};
use hexcue::sources::live::LiveInput;
use hexcue_core::ground::{GroundDetector, GroundSignal};
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::text::{parse_profile, ProfileLoadError, DEFAULT_PROFILE_TOML};
use hexcue_core::profile::GroundDetection;
use hexcue_core::profile::Profile;
use hexcue_core::summary::Summary;

const FT: f64 = 0.3048;
const KT: f64 = 1852.0 / 3600.0;
/// The heading at the simulator's time 0 (deg): 0 is the held sample before any input.
const HEADING_AT_0_DEG: f64 = 10.0;

/// The default profile with `[ground] motion_gain = 0.4` and `extra` after it.
fn profile(extra: &str) -> Result<Profile, ProfileLoadError> {
    parse_profile(
        &format!("{DEFAULT_PROFILE_TOML}\n[ground]\nmotion_gain = 0.4\n{extra}\n"),
        "ground.toml",
    )
}

/// What the simulator says of the ground at its time t: the gears' weight on wheels (nose,
/// left main, right main, tail), height above ground (m), ground speed (m/s).
#[derive(Clone, Copy, Debug)]
struct Said {
    wow: [bool; 4],
    height_m: f64,
    speed_mps: f64,
}

/// A C172's circuit as its gears see it: taxiing on three wheels, the take-off run on the
/// mains (nose wheel up), lift-off at 6 s, a touchdown on the right main wheel alone at 10 s.
fn circuit(t: f64) -> Said {
    let (wow, height_m, speed_mps) = if t < 3.0 {
        ([true, true, true, false], 1.0, 8.0)
    } else if t < 6.0 {
        ([false, true, true, false], 1.1, 25.0)
    } else if t < 10.0 {
        ([false; 4], 1.5 + 5.0 * (t - 6.0), 35.0)
    } else {
        ([false, false, true, false], 1.0, 30.0)
    };
    Said {
        wow,
        height_m,
        speed_mps,
    }
}

/// Height and speed alone, chosen about the thresholds of [`LOW_THRESHOLDS`]: below both at
/// first; between them (held on the ground); above 2 m at 6 s (in the air); below both at
/// 9 s. The defaults (3 m, 30 m/s; 6 m, 36 m/s) would call all of it ground.
fn hover_taxi(t: f64) -> Said {
    let (height_m, speed_mps) = if t < 3.0 {
        (0.5, 5.0)
    } else if t < 6.0 {
        (1.5, 12.0)
    } else if t < 9.0 {
        (2.5, 20.0)
    } else {
        (0.6, 7.0)
    };
    Said {
        wow: [false; 4],
        height_m,
        speed_mps,
    }
}

const LOW_THRESHOLDS: &str = "[ground_detection]\non_ground_below_m = 1.0\n\
                              on_ground_slower_mps = 8.0\nin_air_above_m = 2.0\n\
                              in_air_faster_mps = 15.0";

/// One step as the session made it.
struct Seen {
    /// The step's time on the session's clock (s).
    t_s: f64,
    /// The simulator's time of the sample used (`None`: no input yet).
    sim_t_s: Option<f64>,
    input_age_s: Option<f64>,
    orders: LaneOrders,
    events: Vec<String>,
}

/// A live session of the CWF on `profile` from `url` for `steps` steps; `simulator` starts
/// once the session listens (its algorithms built), so that the simulator's time and the
/// session's run together.
fn fly(profile: &Profile, url: &str, steps: u64, simulator: impl FnOnce()) -> (Vec<Seen>, Summary) {
    let input = LiveInput::open(url).unwrap();
    let mut session =
        LiveSession::new(profile, &[AlgorithmId::Cwf], AlgorithmId::Cwf, input).unwrap();
    simulator();
    let mut seen = Vec::new();
    run(
        &mut session,
        |s| {
            if s.stats().commands_out >= steps {
                Control::Stop
            } else {
                Control::Continue
            }
        },
        |r| {
            let heading_deg = r.frame.aircraft.attitude_rad.z.to_degrees();
            seen.push(Seen {
                t_s: r.frame.t_s,
                sim_t_s: (heading_deg != 0.0).then_some(heading_deg - HEADING_AT_0_DEG),
                input_age_s: r.input_age_s,
                orders: r.lanes,
                events: r.events.iter().map(|e| e.text.clone()).collect(),
            })
        },
    )
    .unwrap();
    let (summary, _) = session.finish().unwrap();
    (seen, summary)
}

/// The phase at each step as the core's detector decides it from what the sample used said
/// (`signal`), on the steps with fresh input.
fn expected(
    profile: &Profile,
    seen: &[Seen],
    signal: impl Fn(f64) -> GroundSignal,
    thresholds: GroundDetection,
) -> Vec<bool> {
    let timeout_s = profile.safety.input_timeout_s;
    let mut d = GroundDetector::new(thresholds);
    seen.iter()
        .map(|s| {
            if let (Some(t), Some(age)) = (s.sim_t_s, s.input_age_s) {
                if age <= timeout_s {
                    d.update(&signal(t));
                }
            }
            d.on_ground()
        })
        .collect()
}

/// Each step at which the phase changed, the simulator's time then, and the phase after.
fn changes(seen: &[Seen]) -> Vec<(usize, f64, bool)> {
    let mut out = Vec::new();
    let mut phase = false;
    for (k, s) in seen.iter().enumerate() {
        if s.orders.on_ground != phase {
            phase = s.orders.on_ground;
            out.push((k, s.sim_t_s.unwrap_or(f64::NAN), phase));
        }
    }
    out
}

/// The session's phases are the detector's at every step; its changes happened at the
/// first step whose sample is at or after the script's change (`at`, simulator time), each
/// with its event and its line of the summary, on `basis`.
fn assert_follows(
    seen: &[Seen],
    summary: &Summary,
    want: &[bool],
    at: &[(f64, bool)],
    basis: &str,
) {
    let phases: Vec<bool> = seen.iter().map(|s| s.orders.on_ground).collect();
    let first_diff = phases.iter().zip(want).position(|(a, b)| a != b);
    assert_eq!(
        first_diff, None,
        "the session's phase against the detector's"
    );
    let c = changes(seen);
    eprintln!("changes (step, simulator s, on the ground): {c:?}");
    assert_eq!(c.len(), at.len(), "{c:?}");
    for ((k, t, on), (want_t, want_on)) in c.iter().zip(at) {
        assert_eq!(on, want_on, "{c:?}");
        // (The heading carries the time as an f32 in degrees: 1e-4 s is far above its
        // rounding and far below a sample's period.)
        let mut before = seen[..*k].iter().filter_map(|s| s.sim_t_s);
        assert!(
            *t >= want_t - 1e-4 && before.clone().all(|b| b < want_t - 1e-4),
            "a change at the simulator's {t} s, expected at the first sample from {want_t} s: \
             {c:?}, the sample before {:?}",
            before.next_back()
        );
        let words = if *on {
            format!("on the ground ({basis}): the profile's [ground] tuning blends in")
        } else {
            format!("in the air ({basis}): the air tuning blends back in")
        };
        assert!(
            seen[*k].events.iter().any(|e| e.starts_with(&words)),
            "step {k}: {:?}",
            seen[*k].events
        );
    }
    let logged = &summary.live.as_ref().unwrap().ground_changes;
    assert_eq!(logged.len(), c.len(), "{logged:?}");
    for (l, (k, _, on)) in logged.iter().zip(&c) {
        // The step's own time (a report dropped on the way to the comparison lanes' thread
        // leaves the step count and the reports' apart).
        assert_eq!((l.t_s, l.on_ground), (seen[*k].t_s, *on), "{logged:?}");
        assert_eq!(l.basis, basis);
    }
}

// ---------------------------------------------------------------------------------------------
// FlightGear

/// FlightGear's property values at its time t in its own units: level flight, the heading
/// counting the time, the ground's properties from `said`.
fn flightgear_properties(t: f64, said: Said) -> HashMap<String, f64> {
    let mut p: HashMap<String, f64> = [
        ("/sim/time/elapsed-sec", 100.0 + t),
        ("/sim/freeze/master", 0.0),
        ("/accelerations/pilot/x-accel-fps_sec", 0.0),
        ("/accelerations/pilot/y-accel-fps_sec", 0.0),
        ("/accelerations/pilot/z-accel-fps_sec", -32.174),
        ("/orientation/p-body", 0.0),
        ("/orientation/q-body", 0.0),
        ("/orientation/r-body", 0.0),
        ("/orientation/roll-deg", 0.0),
        ("/orientation/pitch-deg", 0.0),
        ("/orientation/heading-deg", HEADING_AT_0_DEG + t),
        ("/position/altitude-agl-ft", said.height_m / FT),
        ("/velocities/groundspeed-kt", said.speed_mps / KT),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    for (i, w) in said.wow.iter().enumerate() {
        p.insert(format!("/gear/gear[{i}]/wow"), f64::from(u8::from(*w)));
    }
    p
}

/// FlightGear sending `proto` at `frame_hz` (at most once a rendered frame) until `stop`.
fn flightgear(
    port: u16,
    proto: Protocol,
    frame_hz: f64,
    script: fn(f64) -> Said,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let start = Instant::now();
        let mut k = 0u64;
        while !stop.load(Ordering::Relaxed) {
            let due = start + Duration::from_secs_f64(k as f64 / frame_hz);
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
            let t = k as f64 / frame_hz;
            let props = flightgear_properties(t, script(t));
            let props: HashMap<&str, f64> = props.iter().map(|(k, v)| (k.as_str(), *v)).collect();
            let _ = tx.send_to(&datagram(&proto, &props), ("127.0.0.1", port));
            k += 1;
        }
    })
}

fn shipped_protocol() -> Protocol {
    protocol_file(&repo().join("integrations/flightgear/hexcue.xml"))
}

/// What hexcue reads from FlightGear's datagram of `said` (any gear's `wow`), or without the
/// gears' chunks.
fn flightgear_signal(said: Said, gears: bool) -> GroundSignal {
    GroundSignal {
        weight_on_wheels: gears.then(|| said.wow.iter().any(|w| *w)),
        height_agl_m: Some(said.height_m),
        ground_speed_mps: Some(said.speed_mps),
    }
}

#[test]
fn flightgears_weight_on_wheels_takes_the_session_to_the_ground_and_back() {
    let proto = shipped_protocol();
    // The shipped file sends the four gears' wow, the height and the speed.
    let nodes: Vec<&str> = proto.chunks.iter().map(|c| c.node.as_str()).collect();
    assert_eq!(
        nodes[11..],
        [
            "/position/altitude-agl-ft",
            "/velocities/groundspeed-kt",
            "/gear/gear[0]/wow",
            "/gear/gear[1]/wow",
            "/gear/gear[2]/wow",
            "/gear/gear[3]/wow"
        ]
    );
    let profile = profile("").unwrap();
    let port = free_udp_port();
    let url = format!("flightgear://127.0.0.1:{port}");
    let stop = Arc::new(AtomicBool::new(false));
    let mut sender = None;
    let (seen, summary) = fly(&profile, &url, 1150, || {
        sender = Some(flightgear(port, proto, 50.0, circuit, stop.clone()));
    });
    stop.store(true, Ordering::Relaxed);
    sender.unwrap().join().unwrap();
    assert_eq!(summary.live.as_ref().unwrap().malformed, 0);
    let want = expected(
        &profile,
        &seen,
        |t| flightgear_signal(circuit(t), true),
        GroundDetection::default(),
    );
    let first_t = seen.iter().find_map(|s| s.sim_t_s).unwrap();
    assert_follows(
        &seen,
        &summary,
        &want,
        &[(first_t, true), (6.0, false), (10.0, true)],
        "the simulator's weight on wheels",
    );
}

#[test]
fn without_the_gears_chunks_flightgears_height_and_speed_decide_on_the_profiles_thresholds() {
    let mut proto = shipped_protocol();
    // A protocol file for an FDM that sets no gear: the `wow` chunks taken out (52 bytes).
    proto.chunks.retain(|c| !c.node.ends_with("/wow"));
    assert_eq!(proto.chunks.len(), 13);
    let profile = profile(LOW_THRESHOLDS).unwrap();
    let thresholds = profile.ground_detection;
    assert_eq!(thresholds.in_air_above_m, 2.0);
    let port = free_udp_port();
    let url = format!("flightgear://127.0.0.1:{port}");
    let stop = Arc::new(AtomicBool::new(false));
    let mut sender = None;
    let (seen, summary) = fly(&profile, &url, 1100, || {
        sender = Some(flightgear(port, proto, 50.0, hover_taxi, stop.clone()));
    });
    stop.store(true, Ordering::Relaxed);
    sender.unwrap().join().unwrap();
    assert_eq!(summary.live.as_ref().unwrap().malformed, 0);
    let signal = |t| flightgear_signal(hover_taxi(t), false);
    let want = expected(&profile, &seen, signal, thresholds);
    // The default thresholds would have kept the ground throughout: the profile's decided.
    let by_defaults = expected(&profile, &seen, signal, GroundDetection::default());
    assert_ne!(want, by_defaults);
    assert_eq!(
        by_defaults.iter().filter(|g| !**g).count(),
        seen.iter().take_while(|s| s.sim_t_s.is_none()).count(),
        "the defaults: on the ground from the first sample on"
    );
    let first_t = seen.iter().find_map(|s| s.sim_t_s).unwrap();
    assert_follows(
        &seen,
        &summary,
        &want,
        &[(first_t, true), (6.0, false), (9.0, true)],
        "height above ground and ground speed",
    );
}

// ---------------------------------------------------------------------------------------------
// X-Plane

/// X-Plane's datarefs at its time t, as DataRefs.txt gives their units: level flight (1 g
/// normal), the heading counting the time, the ground's from `said` (`onground_any` 1 when
/// any gear is on the ground).
fn xplane_value(t: f64, dataref: &str) -> Option<f32> {
    let said = circuit(t);
    let v = match dataref {
        "sim/flightmodel/forces/g_axil" | "sim/flightmodel/forces/g_side" => 0.0,
        "sim/flightmodel/forces/g_nrml" => 1.0,
        "sim/flightmodel/position/P"
        | "sim/flightmodel/position/Q"
        | "sim/flightmodel/position/R"
        | "sim/flightmodel/position/phi"
        | "sim/flightmodel/position/theta" => 0.0,
        "sim/flightmodel/position/psi" => HEADING_AT_0_DEG + t,
        "sim/time/paused" => 0.0,
        "sim/flightmodel/failures/onground_any" => f64::from(u8::from(said.wow.contains(&true))),
        "sim/flightmodel/position/y_agl" => said.height_m,
        "sim/flightmodel/position/groundspeed" => said.speed_mps,
        _ => return None,
    };
    Some(v as f32)
}

#[test]
fn xplanes_onground_any_takes_the_session_to_the_ground_and_back() {
    let profile = profile("").unwrap();
    // X-Plane's time starts at the session's first subscription, made when it first steps.
    let xplane = FakeXPlane::start(60.0, xplane_value);
    let url = format!("xplane://{}", xplane.addr);
    let (seen, summary) = fly(&profile, &url, 1150, || {});
    let report = xplane.stop();
    assert!(report.unknown.is_empty(), "{:?}", report.unknown);
    let subscribed: Vec<&str> = report.subscribed.iter().map(|(d, _)| d.as_str()).collect();
    for d in [
        "sim/flightmodel/failures/onground_any",
        "sim/flightmodel/position/y_agl",
        "sim/flightmodel/position/groundspeed",
    ] {
        assert!(subscribed.contains(&d), "{subscribed:?}");
    }
    // The session unsubscribed every dataref on its way out.
    assert_eq!(report.unsubscribed, 13);
    assert_eq!(summary.live.as_ref().unwrap().malformed, 0);
    let want = expected(
        &profile,
        &seen,
        |t| {
            let said = circuit(t);
            GroundSignal {
                weight_on_wheels: Some(said.wow.contains(&true)),
                height_agl_m: Some(said.height_m),
                ground_speed_mps: Some(said.speed_mps),
            }
        },
        GroundDetection::default(),
    );
    let first_t = seen.iter().find_map(|s| s.sim_t_s).unwrap();
    assert_follows(
        &seen,
        &summary,
        &want,
        &[(first_t, true), (6.0, false), (10.0, true)],
        "the simulator's weight on wheels",
    );
}

// ---------------------------------------------------------------------------------------------

/// A threshold out of its range is refused when the profile loads, by `hexcue live` itself,
/// naming the key and the range.
#[test]
fn a_bad_threshold_is_refused_with_its_key() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("low.toml");
    std::fs::write(
        &path,
        format!("{DEFAULT_PROFILE_TOML}\n[ground_detection]\nin_air_above_m = 2.5\n"),
    )
    .unwrap();
    let port = free_udp_port();
    let out = hexcue(&[
        "live",
        "--headless",
        "--input",
        &format!("flightgear://127.0.0.1:{port}"),
        "--algorithms",
        "cwf",
        "--duration",
        "1",
        "--profile",
        path.to_str().unwrap(),
    ]);
    let err = stderr(&out);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains(
            "`ground_detection.in_air_above_m`: 2.5 m: expected a height above \
             ground_detection.on_ground_below_m (3 m)"
        ),
        "{err}"
    );
}
