//! Draws what Foxglove's 3D panel gets from a recording, from the recording's own
//! `foxglove.FrameTransforms` and `foxglove.SceneUpdate` messages at one instant, beside plots
//! of the perceived reference against each algorithm (the layout of
//! `integrations/foxglove/hexcue-layout.json`). hexcue's rendering, not a Foxglove screenshot:
//! there is no Foxglove app on the machine that made docs/images/foxglove-scene.png.
//!
//! `cargo run --release --example foxglove_scene -- REC.mcap --at 12.5 -o scene.png`

use std::collections::BTreeMap;

use anyhow::{anyhow, bail, Context, Result};
use foxglove::messages::{Color as FgColor, FrameTransforms, Point3, Pose, SceneUpdate};
use foxglove::Decode;
use hexcue::plot::{algorithm_color, register_font, FONT, REFERENCE_COLOR};
use hexcue_core::mca::AlgorithmId;
use nalgebra::{Isometry3, Point3 as P3, Translation3, UnitQuaternion, Vector3};
use plotters::prelude::*;

struct Args {
    file: String,
    at_s: f64,
    out: String,
}

fn args() -> Result<Args> {
    let mut it = std::env::args().skip(1);
    let (mut file, mut at_s, mut out) = (None, 10.0, None);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--at" => at_s = it.next().context("--at SECONDS")?.parse()?,
            "-o" => out = it.next(),
            _ => file = Some(a),
        }
    }
    Ok(Args {
        file: file.context("usage: foxglove_scene REC.mcap --at S -o OUT.png")?,
        at_s,
        out: out.context("-o OUT.png")?,
    })
}

fn iso(
    t: &Option<foxglove::messages::Vector3>,
    q: &Option<foxglove::messages::Quaternion>,
) -> Isometry3<f64> {
    let t = t
        .as_ref()
        .map_or(Vector3::zeros(), |t| Vector3::new(t.x, t.y, t.z));
    let q = q.as_ref().map_or(UnitQuaternion::identity(), |q| {
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z))
    });
    Isometry3::from_parts(Translation3::from(t), q)
}

fn pose(p: &Option<Pose>) -> Isometry3<f64> {
    p.as_ref()
        .map_or(Isometry3::identity(), |p| iso(&p.position, &p.orientation))
}

/// child frame → (parent frame, pose of the child in the parent).
type Tree = BTreeMap<String, (String, Isometry3<f64>)>;

fn in_world(tree: &Tree, frame: &str) -> Result<Isometry3<f64>> {
    let mut at = Isometry3::identity();
    let mut f = frame.to_string();
    for _ in 0..16 {
        if f == "world" {
            return Ok(at);
        }
        let (parent, p) = tree.get(&f).ok_or_else(|| anyhow!("no transform to {f}"))?;
        at = p * at;
        f = parent.clone();
    }
    bail!("{frame}: the transform chain does not reach world")
}

fn rgba(c: &Option<FgColor>) -> RGBAColor {
    let c = c.unwrap_or(FgColor {
        r: 0.5,
        g: 0.5,
        b: 0.5,
        a: 1.0,
    });
    let u = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    RGBColor(u(c.r), u(c.g), u(c.b)).mix(c.a)
}

/// A view from behind the rigs, to their right and above: world (x forward, y left, z up) to
/// screen (right, down), with depth (larger is farther).
struct Camera {
    rot: UnitQuaternion<f64>,
}

impl Camera {
    fn new(azimuth_deg: f64, elevation_deg: f64) -> Self {
        // Looking along +x from behind, turned by the azimuth, tilted down by the elevation.
        let yaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), azimuth_deg.to_radians());
        let pitch = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), elevation_deg.to_radians());
        Camera { rot: yaw * pitch }
    }

    fn project(&self, p: &P3<f64>) -> (f64, f64, f64) {
        // Camera frame: x along the view, y left, z up.
        let c = self.rot.inverse() * p.coords;
        // Screen y grows downwards in the drawing area's pixel order.
        (-c.y, -c.z, c.x)
    }
}

struct Shape {
    depth: f64,
    points: Vec<(f64, f64)>,
    colour: RGBAColor,
    filled: bool,
    width: u32,
}

fn point(p: &Point3) -> P3<f64> {
    P3::new(p.x, p.y, p.z)
}

fn main() -> Result<()> {
    let args = args()?;
    let bytes = std::fs::read(&args.file).with_context(|| args.file.clone())?;
    let mut start_ns = None;
    let mut series: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    let mut tfs: BTreeMap<String, Vec<(u64, Vec<u8>)>> = BTreeMap::new();
    let mut scenes: BTreeMap<String, Vec<(u64, Vec<u8>)>> = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes)? {
        let m = m?;
        let topic = m.channel.topic.clone();
        if topic == "/aircraft" {
            let v: serde_json::Value = serde_json::from_slice(&m.data)?;
            let t = v["t"].as_f64().unwrap_or(0.0);
            start_ns.get_or_insert(m.log_time - (t * 1e9).round() as u64);
        }
        if topic.ends_with("/perceived") {
            let v: serde_json::Value = serde_json::from_slice(&m.data)?;
            let t = v["t"].as_f64().unwrap_or(0.0);
            for (i, ch) in ["fx", "fy"].iter().enumerate() {
                let y = v["specific_force"][i].as_f64().unwrap_or(f64::NAN);
                series
                    .entry(format!("{topic} {ch}"))
                    .or_default()
                    .push((t, y));
            }
        } else if topic.ends_with("/tf") {
            tfs.entry(topic)
                .or_default()
                .push((m.log_time, m.data.into_owned()));
        } else if topic.ends_with("/scene") {
            scenes
                .entry(topic)
                .or_default()
                .push((m.log_time, m.data.into_owned()));
        }
    }
    let start_ns = start_ns.context("no /aircraft message")?;
    let at_ns = start_ns + (args.at_s * 1e9).round() as u64;
    // The message of each topic in force at the instant: the last one at or before it.
    let latest = |msgs: &Vec<(u64, Vec<u8>)>| -> Option<Vec<u8>> {
        msgs.iter()
            .rev()
            .find(|(t, _)| *t <= at_ns)
            .map(|(_, d)| d.clone())
    };
    let mut tree = Tree::new();
    for msgs in tfs.values() {
        let tf = FrameTransforms::decode(&latest(msgs).context("no transform yet")?[..])?;
        for t in tf.transforms {
            tree.insert(
                t.child_frame_id,
                (t.parent_frame_id, iso(&t.translation, &t.rotation)),
            );
        }
    }

    let camera = Camera::new(-32.0, 28.0);
    let mut shapes = Vec::new();
    let mut labels = Vec::new();
    // The floor: a grid in the world's z = 0 plane.
    for i in -12..=12 {
        let s = i as f64;
        for (a, b) in [
            (P3::new(s, -12.0, 0.0), P3::new(s, 12.0, 0.0)),
            (P3::new(-12.0, s, 0.0), P3::new(12.0, s, 0.0)),
        ] {
            let (pa, pb) = (camera.project(&a), camera.project(&b));
            shapes.push(Shape {
                depth: f64::INFINITY,
                points: vec![(pa.0, pa.1), (pb.0, pb.1)],
                colour: RGBColor(200, 200, 205).mix(1.0),
                filled: false,
                width: 1,
            });
        }
    }
    for msgs in scenes.values() {
        let scene = SceneUpdate::decode(&latest(msgs).context("no scene yet")?[..])?;
        for e in &scene.entities {
            let frame = in_world(&tree, &e.frame_id)?;
            let to_screen =
                |local: &Isometry3<f64>, p: &Point3| camera.project(&(frame * local * point(p)));
            for tri in &e.triangles {
                let local = pose(&tri.pose);
                for t in tri.points.chunks(3) {
                    let p: Vec<(f64, f64, f64)> = t.iter().map(|p| to_screen(&local, p)).collect();
                    shapes.push(Shape {
                        depth: p.iter().map(|q| q.2).sum::<f64>() / 3.0,
                        points: p.iter().map(|q| (q.0, q.1)).collect(),
                        colour: rgba(&tri.color),
                        filled: true,
                        width: 1,
                    });
                }
            }
            for line in &e.lines {
                let local = pose(&line.pose);
                let p: Vec<(f64, f64, f64)> =
                    line.points.iter().map(|p| to_screen(&local, p)).collect();
                let mut pts: Vec<(f64, f64)> = p.iter().map(|q| (q.0, q.1)).collect();
                if line.r#type == foxglove::messages::line_primitive::Type::LineLoop as i32 {
                    pts.push(pts[0]);
                }
                shapes.push(Shape {
                    depth: p.iter().map(|q| q.2).sum::<f64>() / p.len().max(1) as f64 - 0.01,
                    points: pts,
                    colour: rgba(&line.color),
                    filled: false,
                    width: (line.thickness * 60.0).round().max(1.0) as u32,
                });
            }
            for s in &e.spheres {
                let c = to_screen(
                    &pose(&s.pose),
                    &Point3 {
                        x: 0.0,
                        y: 0.0,
                        z: 0.0,
                    },
                );
                let r = 0.5 * s.size.as_ref().map_or(0.2, |v| v.x);
                let ring: Vec<(f64, f64)> = (0..=16)
                    .map(|k| {
                        let a = k as f64 / 16.0 * std::f64::consts::TAU;
                        (c.0 + r * a.cos(), c.1 + r * a.sin())
                    })
                    .collect();
                shapes.push(Shape {
                    depth: c.2 - 0.02,
                    points: ring,
                    colour: rgba(&s.color),
                    filled: true,
                    width: 1,
                });
            }
            for t in &e.texts {
                let c = to_screen(
                    &pose(&t.pose),
                    &Point3 {
                        x: 0.0,
                        y: 0.0,
                        z: 0.0,
                    },
                );
                labels.push((c, t.text.clone(), rgba(&t.color)));
            }
        }
    }
    // Painter's order: farthest first.
    shapes.sort_by(|a, b| b.depth.total_cmp(&a.depth));

    register_font()?;
    let root = BitMapBackend::new(&args.out, (1600, 900)).into_drawing_area();
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(900);
    let title = format!(
        "t = {:.2} s: hexcue's rendering of its /tf and /scene messages (not a Foxglove screenshot)",
        args.at_s
    );
    let (head, body) = left.split_vertically(40);
    head.draw(&Text::new(title, (10, 12), (FONT, 15).into_font()))?;
    let (xs, ys): (Vec<f64>, Vec<f64>) = shapes
        .iter()
        .filter(|s| s.depth.is_finite())
        .flat_map(|s| s.points.clone())
        .unzip();
    let span = |v: &[f64]| {
        let (lo, hi) = v
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), x| (l.min(*x), h.max(*x)));
        (lo - 0.8, hi + 0.8)
    };
    let (mut x0, mut x1) = span(&xs);
    let (y0, y1) = span(&ys);
    // Equal scales on both axes: widen x to the area's aspect.
    let (w, h) = body.dim_in_pixel();
    let want = (y1 - y0) * w as f64 / h as f64;
    if want > x1 - x0 {
        let pad = (want - (x1 - x0)) / 2.0;
        x0 -= pad;
        x1 += pad;
    }
    let y1 = y0 + (x1 - x0) * h as f64 / w as f64;
    let area = body.apply_coord_spec(Cartesian2d::<
        plotters::coord::types::RangedCoordf64,
        plotters::coord::types::RangedCoordf64,
    >::new(x0..x1, y0..y1, (0..w as i32, 0..h as i32)));
    for s in &shapes {
        if s.filled {
            area.draw(&Polygon::new(s.points.clone(), s.colour.filled()))?;
        } else {
            area.draw(&PathElement::new(
                s.points.clone(),
                s.colour.stroke_width(s.width),
            ))?;
        }
    }
    for ((x, y, _), text, colour) in labels {
        area.draw(&Text::new(
            text,
            (x - 0.3, y),
            (FONT, 26).into_font().color(&colour),
        ))?;
    }

    // Reference against each algorithm, as the layout's plots.
    let panels = right.split_evenly((2, 1));
    for (panel, ch) in panels.iter().zip(["fx", "fy"]) {
        let mut lines = vec![(
            "reference".to_string(),
            "/aircraft/perceived".to_string(),
            REFERENCE_COLOR,
        )];
        for alg in AlgorithmId::ALL {
            let topic = format!("/{}/perceived", alg.key());
            if series.contains_key(&format!("{topic} {ch}")) {
                lines.push((alg.key().to_string(), topic, algorithm_color(*alg)));
            }
        }
        let all: Vec<&(f64, f64)> = lines
            .iter()
            .flat_map(|(_, t, _)| series[&format!("{t} {ch}")].iter())
            .collect();
        let t1 = all.iter().map(|p| p.0).fold(0.0, f64::max);
        let (lo, hi) = all
            .iter()
            .filter(|p| p.1.is_finite())
            .fold((f64::MAX, f64::MIN), |(l, h), p| (l.min(p.1), h.max(p.1)));
        let pad = 0.1 * (hi - lo).max(1e-3);
        let mut chart = ChartBuilder::on(panel)
            .margin(12)
            .caption(format!("perceived {ch} (m/s²)"), (FONT, 18))
            .x_label_area_size(30)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..t1, (lo - pad)..(hi + pad))?;
        chart
            .configure_mesh()
            .x_desc("trace time (s)")
            .label_style((FONT, 12))
            .light_line_style(RGBColor(240, 240, 240))
            .draw()?;
        for (name, topic, colour) in &lines {
            let data = series[&format!("{topic} {ch}")].clone();
            chart
                .draw_series(LineSeries::new(data, colour.stroke_width(2)))?
                .label(name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], colour.stroke_width(2))
                });
        }
        chart.draw_series(std::iter::once(PathElement::new(
            vec![(args.at_s, lo - pad), (args.at_s, hi + pad)],
            BLACK.mix(0.4).stroke_width(1),
        )))?;
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK.mix(0.3))
            .label_font((FONT, 13))
            .position(SeriesLabelPosition::UpperRight)
            .draw()?;
    }
    root.present()?;
    eprintln!("wrote {}", args.out);
    Ok(())
}
