//! Actuator positions from a pose, for the controllers of hobby and prosumer hexapods that
//! take each actuator's position rather than a pose (docs/live.md, *Actuator streams*): the
//! profile's `[actuators]` section ([`ActuatorParams`]), compiled once when the profile is
//! loaded into [`Actuators`], which turns each step's legs into six positions of 0 …
//! 2^bits − 1 and those into the controller's byte frame ([`frame`]). Pure: no I/O.
//!
//! - `linear`: a leg's length over its stroke, position = round((l − leg_min) / (leg_max −
//!   leg_min) × (2^bits − 1)).
//! - `rotary`: a servo crank and a rod per actuator; the crank angle from the inverse
//!   kinematics ([`rotary`]), position = round((α − α_min) / (α_max − α_min) × (2^bits − 1)).
//!
//! Then, per frame actuator N (the rig's numbering): the position of hexcue's leg
//! `order[N − 1]`, inverted (2^bits − 1 − p) when `invert[N − 1]`, plus `offset[N − 1]`
//! counts, kept within 0 … 2^bits − 1.

pub mod frame;
pub mod rotary;

use nalgebra::{Vector3, Vector6};
use serde::{Deserialize, Serialize};

use crate::model::stewart::Stewart;
use crate::vocab::ProfileError;
pub use frame::{Encoding, FrameFormat, FrameParseError};
use rotary::{Crank, CrankAngle};

/// The profile's `[actuators]` section, as written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuatorParams {
    /// `linear` or `rotary`.
    pub kind: String,
    /// The position frame: `<AxisNa>`, `<n>` and literal text.
    pub template: String,
    /// Resolution of a position (8–24 bits).
    pub bits: u32,
    /// `binary` (big-endian), `decimal` or `hex`.
    pub encoding: String,
    /// Sent once when the platform engages (same language, no positions).
    #[serde(default)]
    pub start: String,
    /// Sent once after the platform has parked for good.
    #[serde(default)]
    pub stop: String,
    /// Per frame actuator: count down from full scale instead of up.
    #[serde(default)]
    pub invert: [bool; 6],
    /// Per frame actuator: counts added after scaling (and inversion).
    #[serde(default)]
    pub offset: [i64; 6],
    /// Per frame actuator N: the hexcue leg (1–6) whose position it takes. Default 1..6.
    #[serde(default = "identity_order")]
    pub order: [u8; 6],
    /// Rotary: the servo arm, pivot to rod joint (m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crank_radius_m: Option<f64>,
    /// Rotary: the rod, joint to joint (m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rod_length_m: Option<f64>,
    /// Rotary: each leg's arm direction in the base plane, from x forward toward y right
    /// (deg), in hexcue's leg order.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arm_angles_deg: Option<[f64; 6]>,
    /// Rotary: the crank's travel, from the horizontal, positive up (deg).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crank_min_deg: Option<f64>,
    /// Rotary: the crank's upper travel limit, from the horizontal, positive up (deg).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crank_max_deg: Option<f64>,
}

fn identity_order() -> [u8; 6] {
    [1, 2, 3, 4, 5, 6]
}

/// How a leg's position is found.
#[derive(Clone, Debug, PartialEq)]
enum Kind {
    Linear { min_m: f64, max_m: f64 },
    Rotary { cranks: Box<[Crank; 6]> },
}

/// One step's actuator positions, in the frame's order (the rig's numbering).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ActuatorPositions {
    /// Positions 0 … 2^bits − 1, as they go into the frame.
    pub counts: [u32; 6],
    /// Rotary: each frame actuator's crank angle (rad); linear: the leg length (m).
    pub raw: [f64; 6],
    /// Frame actuators (bit N − 1) whose pose the actuator cannot give: the nearest it can
    /// was sent instead.
    pub limited: u8,
}

/// `[actuators]` compiled: the mapping from legs to positions and the frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Actuators {
    kind: Kind,
    frame: FrameFormat,
    invert: [bool; 6],
    offset: [i64; 6],
    /// Hexcue leg index (0..6) of each frame actuator.
    order: [usize; 6],
}

fn err(key: &str, reason: String) -> ProfileError {
    ProfileError {
        key: format!("actuators.{key}"),
        reason,
    }
}

impl Actuators {
    /// Compiles the section against the platform it drives; every error names its key.
    pub fn new(p: &ActuatorParams, stewart: &Stewart) -> Result<Self, ProfileError> {
        let encoding = Encoding::from_key(&p.encoding).ok_or_else(|| {
            err(
                "encoding",
                format!(
                    "\"{}\": expected \"binary\", \"decimal\" or \"hex\"",
                    p.encoding
                ),
            )
        })?;
        let frame = FrameFormat::new(&p.template, &p.start, &p.stop, p.bits, encoding)?;
        let full = frame.full_scale() as i64;
        for (i, o) in p.offset.iter().enumerate() {
            if o.abs() > full {
                return Err(err(
                    &format!("offset[{i}]"),
                    format!("{o}: expected at most ±{full} counts (2^bits − 1)"),
                ));
            }
        }
        let mut seen = [false; 6];
        let mut order = [0usize; 6];
        for (i, &leg) in p.order.iter().enumerate() {
            if !(1..=6).contains(&leg) || seen[leg as usize - 1] {
                return Err(err(
                    "order",
                    format!(
                        "{:?}: expected each hexcue leg 1-6 once (order[N-1] is the leg that \
                         drives the rig's actuator N)",
                        p.order
                    ),
                ));
            }
            seen[leg as usize - 1] = true;
            order[i] = leg as usize - 1;
        }
        let rotary_keys = [
            ("crank_radius_m", p.crank_radius_m.is_some()),
            ("rod_length_m", p.rod_length_m.is_some()),
            ("arm_angles_deg", p.arm_angles_deg.is_some()),
            ("crank_min_deg", p.crank_min_deg.is_some()),
            ("crank_max_deg", p.crank_max_deg.is_some()),
        ];
        let kind = match p.kind.as_str() {
            "linear" => {
                if let Some((key, _)) = rotary_keys.iter().find(|(_, given)| *given) {
                    return Err(err(
                        key,
                        "is a rotary key; kind = \"linear\" takes the stroke from the \
                         geometry's leg_min_m and leg_max_m"
                            .into(),
                    ));
                }
                Kind::Linear {
                    min_m: stewart.leg_min_m,
                    max_m: stewart.leg_max_m,
                }
            }
            "rotary" => {
                if let Some((key, _)) = rotary_keys.iter().find(|(_, given)| !*given) {
                    return Err(err(key, "missing: kind = \"rotary\" needs it".into()));
                }
                let a = p.crank_radius_m.unwrap_or_default();
                let s = p.rod_length_m.unwrap_or_default();
                crate::vocab::positive("actuators.crank_radius_m", a)?;
                crate::vocab::positive("actuators.rod_length_m", s)?;
                let (lo, hi) = (
                    p.crank_min_deg.unwrap_or_default(),
                    p.crank_max_deg.unwrap_or_default(),
                );
                if !(lo.is_finite() && hi.is_finite() && lo < hi && lo >= -90.0 && hi <= 90.0) {
                    return Err(err(
                        "crank_min_deg",
                        format!(
                            "[{lo}, {hi}]: expected crank_min_deg < crank_max_deg, both within \
                             ±90° of the horizontal"
                        ),
                    ));
                }
                let arms = p.arm_angles_deg.unwrap_or_default();
                if let Some(i) = arms.iter().position(|b| !b.is_finite()) {
                    return Err(err(
                        &format!("arm_angles_deg[{i}]"),
                        format!("{}: expected a finite angle (deg)", arms[i]),
                    ));
                }
                let cranks = Box::new(std::array::from_fn(|i| {
                    let b = arms[i].to_radians();
                    Crank {
                        radius_m: a,
                        rod_m: s,
                        arm: (b.cos(), b.sin()),
                        min_rad: lo.to_radians(),
                        max_rad: hi.to_radians(),
                    }
                }));
                Kind::Rotary { cranks }
            }
            other => {
                return Err(err(
                    "kind",
                    format!("\"{other}\": expected \"linear\" or \"rotary\""),
                ))
            }
        };
        let actuators = Actuators {
            kind,
            frame,
            invert: p.invert,
            offset: p.offset,
            order,
        };
        // A rig whose cranks cannot hold the neutral pose is written wrong (an arm angle,
        // the radius or the rod), not a pose to limit.
        if let Kind::Rotary { cranks } = &actuators.kind {
            let (base, plat) = (&stewart.base_joints_m, &stewart.platform_joints_m);
            for (i, crank) in cranks.iter().enumerate() {
                if let CrankAngle::Limited(_) = crank.angle(&base[i], &plat[i]) {
                    return Err(err(
                        &format!("arm_angles_deg[{i}]"),
                        format!(
                            "leg {}: at the neutral pose no crank angle within [{}°, {}°] \
                             puts the rod ({} m) on the platform joint; check the arm angle, \
                             crank_radius_m, rod_length_m and the geometry's joints",
                            i + 1,
                            p.crank_min_deg.unwrap_or_default(),
                            p.crank_max_deg.unwrap_or_default(),
                            p.rod_length_m.unwrap_or_default()
                        ),
                    ));
                }
            }
        }
        Ok(actuators)
    }

    /// The frame each step's positions are written in.
    pub fn frame(&self) -> &FrameFormat {
        &self.frame
    }

    /// Whether the rig's actuators are rotary cranks (positions are crank angles) rather than
    /// linear legs (positions are leg lengths).
    pub fn is_rotary(&self) -> bool {
        matches!(self.kind, Kind::Rotary { .. })
    }

    /// The positions for a pose whose legs are `legs_m` on `stewart`: the crank angles of a
    /// rotary rig come from the pose's platform joints, a linear rig's positions from the
    /// legs. Nothing allocated.
    pub fn positions(
        &self,
        stewart: &Stewart,
        pose: &Vector6<f64>,
        legs_m: &Vector6<f64>,
    ) -> ActuatorPositions {
        let full = self.frame.full_scale();
        let mut fraction = [0.0f64; 6];
        let mut raw = [0.0f64; 6];
        let mut limited_leg = [false; 6];
        match &self.kind {
            Kind::Linear { min_m, max_m } => {
                for i in 0..6 {
                    let f = (legs_m[i] - min_m) / (max_m - min_m);
                    limited_leg[i] = !(0.0..=1.0).contains(&f);
                    fraction[i] = if f.is_finite() {
                        f.clamp(0.0, 1.0)
                    } else {
                        0.5
                    };
                    raw[i] = legs_m[i];
                }
            }
            Kind::Rotary { cranks } => {
                let r = crate::model::stewart::rotation(pose[3], pose[4], pose[5]);
                let t = Vector3::new(pose[0], pose[1], pose[2]);
                for (i, crank) in cranks.iter().enumerate() {
                    let joint = t + r * stewart.platform_joints_m[i];
                    let angle = crank.angle(&stewart.base_joints_m[i], &joint);
                    limited_leg[i] = matches!(angle, CrankAngle::Limited(_));
                    raw[i] = angle.rad();
                    fraction[i] = (angle.rad() - crank.min_rad) / (crank.max_rad - crank.min_rad);
                }
            }
        }
        let mut out = ActuatorPositions::default();
        for n in 0..6 {
            let leg = self.order[n];
            let mut v = (fraction[leg] * full as f64).round() as i64;
            if self.invert[n] {
                v = full as i64 - v;
            }
            v = (v + self.offset[n]).clamp(0, full as i64);
            out.counts[n] = v as u32;
            out.raw[n] = raw[leg];
            if limited_leg[leg] {
                out.limited |= 1 << n;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::text::default_profile;

    fn params(kind: &str) -> ActuatorParams {
        ActuatorParams {
            kind: kind.into(),
            template: "<255><255><Axis1a><Axis2a><Axis3a><Axis4a><Axis5a><Axis6a>000000<10><13>"
                .into(),
            bits: 24,
            encoding: "binary".into(),
            start: String::new(),
            stop: String::new(),
            invert: [false; 6],
            offset: [0; 6],
            order: identity_order(),
            crank_radius_m: None,
            rod_length_m: None,
            arm_angles_deg: None,
            crank_min_deg: None,
            crank_max_deg: None,
        }
    }

    #[test]
    fn linear_positions_are_the_legs_over_their_stroke() {
        let p = default_profile();
        let s = p.stewart();
        let a = Actuators::new(&params("linear"), &s).unwrap();
        let (lo, hi) = (s.leg_min_m, s.leg_max_m);
        let stroke = hi - lo;
        let legs = Vector6::new(
            lo,
            hi,
            lo + 0.2 * stroke,
            lo + 0.25 * stroke,
            hi + 0.1,
            lo - 1e-3,
        );
        let got = a.positions(&s, &Vector6::zeros(), &legs);
        let full = 16_777_215u32;
        // 0.2 × 16777215 = 3355443; 0.25 × 16777215 = 4194303.75.
        assert_eq!(got.counts, [0, full, 3_355_443, 4_194_304, full, 0]);
        assert_eq!(got.limited, 0b11_0000);
        // The rig's own numbering, inversion and trim.
        let mut q = params("linear");
        q.order = [2, 1, 3, 4, 5, 6];
        q.invert = [true, false, false, false, false, false];
        q.offset = [0, 0, -8, 0, 0, 5];
        let b = Actuators::new(&q, &s).unwrap();
        let got = b.positions(&s, &Vector6::zeros(), &legs);
        assert_eq!(got.counts, [0, 0, 3_355_435, 4_194_304, full, 5]);
        assert_eq!(got.raw[0], hi);
    }

    fn shipped(name: &str) -> crate::profile::Profile {
        let path = format!(
            "{}/profiles/{name}",
            concat!(env!("CARGO_MANIFEST_DIR"), "/..")
        );
        let text = std::fs::read_to_string(&path).unwrap();
        crate::profile::text::parse_profile(&text, &path).unwrap()
    }

    /// The shipped rotary rig at neutral has every crank horizontal (its geometry puts the
    /// rods there), and a pure heave moves every crank alike, up for up.
    #[test]
    fn the_rotary_profile_is_knaufinators_rig_at_neutral() {
        let p = shipped("hobby-rotary.toml");
        let s = p.stewart();
        let a = p.actuators().unwrap().unwrap();
        assert!(a.is_rotary());
        let at = |pose: Vector6<f64>| a.positions(&s, &pose, &s.leg_lengths(&pose));
        let n = at(Vector6::zeros());
        assert_eq!(n.limited, 0);
        for c in n.raw {
            // The repository's platform height is rounded to 7 decimals of an inch.
            assert!(c.abs() < 1e-3, "{c}");
        }
        // Mid-scale, counted up or down (cranks 1, 3, 5 inverted): 32767.5 either way.
        for (i, c) in n.counts.iter().enumerate() {
            assert!((32_767..=32_768).contains(c), "crank {}: {c}", i + 1);
        }
        let up = at(Vector6::new(0.0, 0.0, -0.05, 0.0, 0.0, 0.0));
        // Alike to the joints' 5 decimals (10 µm).
        for c in up.raw {
            assert!((c - up.raw[0]).abs() < 1e-3 && c > 0.1, "{:?}", up.raw);
        }
        assert!(up.counts[1] > n.counts[1] && up.counts[0] < n.counts[0]);
    }

    /// The numbers the hobby profiles' comments give: each axis alone at its limit, the
    /// legs' (and the cranks') extremes; and the rotary rig's cranks in pure heave at its
    /// leg bounds.
    #[test]
    fn the_hobby_profiles_comments_hold() {
        let extremes = |p: &crate::profile::Profile, axes: &[usize]| {
            let s = p.stewart();
            let a = p.actuators().unwrap().unwrap();
            let ex = p.limits.si().excursion;
            let (mut lo, mut hi, mut crank) = (f64::INFINITY, 0.0f64, 0.0f64);
            for &axis in axes {
                for sign in [-1.0, 1.0] {
                    let mut pose = Vector6::zeros();
                    pose[axis] = sign * ex[axis];
                    let legs = s.leg_lengths(&pose);
                    lo = lo.min(legs.min());
                    hi = hi.max(legs.max());
                    let got = a.positions(&s, &pose, &legs);
                    assert_eq!(got.limited, 0);
                    if a.is_rotary() {
                        crank = got.raw.iter().fold(crank, |m, c| m.max(c.abs()));
                    }
                }
            }
            (lo, hi, crank.to_degrees())
        };
        let near = |x: f64, want: f64, tol: f64| assert!((x - want).abs() <= tol, "{x} vs {want}");
        let linear = shipped("hobby-linear.toml");
        let (lo, hi, _) = extremes(&linear, &[0, 1, 2, 3, 4, 5]);
        near(lo, 0.7394, 5e-5);
        near(hi, 0.9535, 5e-5);
        let (lo, hi, _) = extremes(&linear, &[2]);
        near(lo, 0.7797, 5e-4);
        near(hi, 0.9126, 5e-4);
        let rotary = shipped("hobby-rotary.toml");
        let (lo, hi, crank) = extremes(&rotary, &[0, 1, 2, 3, 4, 5]);
        near(lo, 0.583, 5e-4);
        near(hi, 0.743, 5e-4);
        assert!(crank < 32.0 && crank > 31.0, "{crank}");
        let s = rotary.stewart();
        let a = rotary.actuators().unwrap().unwrap();
        let heave_crank = |dz: f64| {
            let pose = Vector6::new(0.0, 0.0, dz, 0.0, 0.0, 0.0);
            a.positions(&s, &pose, &s.leg_lengths(&pose)).raw[0].to_degrees()
        };
        near(heave_crank(-0.07), 20.5, 0.05);
        near(heave_crank(0.07), -25.2, 0.05);
        // The heave that puts the legs at each bound, by bisection.
        for (leg, dz_want, crank_want) in [(0.82, -0.160, 46.8), (0.57, 0.096, -38.1)] {
            let (mut up, mut down) = (-0.3, 0.3);
            for _ in 0..100 {
                let mid = 0.5 * (up + down);
                let l = s.leg_lengths(&Vector6::new(0.0, 0.0, mid, 0.0, 0.0, 0.0))[0];
                if l > leg {
                    up = mid;
                } else {
                    down = mid;
                }
            }
            near(up, dz_want, 5e-4);
            near(heave_crank(up), crank_want, 0.05);
        }
    }

    /// Poses drawn across the rotary profile's limits (a fixed sequence): every one whose
    /// virtual legs the limiter would let through (inside the margin) has every crank
    /// within its travel, checked by putting each rod's end back on its joint.
    #[test]
    fn the_rotary_profile_reaches_every_pose_its_limiter_allows() {
        let p = shipped("hobby-rotary.toml");
        let s = p.stewart();
        let a = p.actuators().unwrap().unwrap();
        let ex = p.limits.si().excursion;
        let margin = p.limiter.leg_margin_m;
        let Kind::Rotary { cranks } = &a.kind else {
            panic!("rotary")
        };
        let mut seed: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut uniform = || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let (mut allowed, mut worst) = (0, 0.0f64);
        for _ in 0..20_000 {
            let pose = Vector6::from_fn(|i, _| ex[i] * uniform());
            let legs = s.leg_lengths(&pose);
            if legs
                .iter()
                .any(|l| *l < s.leg_min_m + margin || *l > s.leg_max_m - margin)
            {
                continue;
            }
            allowed += 1;
            let got = a.positions(&s, &pose, &legs);
            assert_eq!(got.limited, 0, "{pose:?}: {:?}", got.raw);
            let r = crate::model::stewart::rotation(pose[3], pose[4], pose[5]);
            for (i, c) in cranks.iter().enumerate() {
                let joint = Vector3::new(pose[0], pose[1], pose[2]) + r * s.platform_joints_m[i];
                let alpha = got.raw[i];
                let end = s.base_joints_m[i]
                    + c.radius_m
                        * Vector3::new(alpha.cos() * c.arm.0, alpha.cos() * c.arm.1, -alpha.sin());
                assert!(((joint - end).norm() - c.rod_m).abs() < 1e-9);
                worst = worst.max(alpha.abs());
            }
        }
        assert!(allowed > 10_000, "{allowed}");
        assert!(
            worst.to_degrees() < 60.0 && worst.to_degrees() > 40.0,
            "{worst}"
        );
    }

    #[test]
    fn bad_keys_are_refused_by_name() {
        let s = default_profile().stewart();
        let check = |edit: &dyn Fn(&mut ActuatorParams), key: &str, words: &str| {
            let mut p = params("linear");
            edit(&mut p);
            let e = Actuators::new(&p, &s).unwrap_err();
            assert_eq!(e.key, key, "{e}");
            assert!(e.reason.contains(words), "{e}");
        };
        check(&|p| p.kind = "belt".into(), "actuators.kind", "\"rotary\"");
        check(
            &|p| p.encoding = "bcd".into(),
            "actuators.encoding",
            "\"hex\"",
        );
        check(&|p| p.order = [1, 1, 3, 4, 5, 6], "actuators.order", "once");
        check(&|p| p.order = [0, 2, 3, 4, 5, 6], "actuators.order", "1-6");
        check(
            &|p| p.offset[2] = 1 << 24,
            "actuators.offset[2]",
            "±16777215",
        );
        check(
            &|p| p.crank_radius_m = Some(0.1),
            "actuators.crank_radius_m",
            "rotary key",
        );
        check(
            &|p| p.kind = "rotary".into(),
            "actuators.crank_radius_m",
            "missing",
        );
    }
}
