//! Plans grasps on a ray-cast scene of 6 objects with the analytic baseline
//! network, prints the objects and the ranked grasps, and writes a picture:
//! the depth image with the grasps drawn on it, and each object's three
//! views with the chosen one framed and its grasp drawn.
//!
//! ```text
//! cargo run --release -p mvgrasp-core --example demo -- [out.png] [--save-scene DIR]
//! ```
//!
//! `--save-scene DIR` also writes the frame as `DIR/depth.png` (16-bit
//! millimetres) and `DIR/camera.json` (intrinsics, `world_from_camera`,
//! workspace): the sample scene other tools read.

#![allow(clippy::expect_used)] // a demo stops on a broken fixture

use std::fs::File;
use std::io::BufWriter;

use mvgrasp_core::{GraspNet, MomentsNet, PlanOptions, Planner, PlannerConfig, Workspace};
use nalgebra::{Point3, Vector3};

#[path = "../tests/pipeline/scene.rs"]
#[allow(dead_code, clippy::all)]
mod scene;

/// An RGB canvas.
struct Canvas {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
}

impl Canvas {
    fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            rgb: vec![24; width * height * 3],
        }
    }

    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            let i = (y as usize * self.width + x as usize) * 3;
            self.rgb[i..i + 3].copy_from_slice(&c);
        }
    }

    fn line(&mut self, a: (f64, f64), b: (f64, f64), c: [u8; 3]) {
        let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
            for (dx, dy) in [(0, 0), (1, 0), (0, 1)] {
                self.put(x.round() as i64 + dx, y.round() as i64 + dy, c);
            }
        }
    }

    fn rect(&mut self, x0: usize, y0: usize, w: usize, h: usize, c: [u8; 3]) {
        let (x0, y0, x1, y1) = (x0 as f64, y0 as f64, (x0 + w - 1) as f64, (y0 + h - 1) as f64);
        self.line((x0, y0), (x1, y0), c);
        self.line((x1, y0), (x1, y1), c);
        self.line((x1, y1), (x0, y1), c);
        self.line((x0, y1), (x0, y0), c);
    }

    fn save(&self, path: &str) {
        let file = BufWriter::new(File::create(path).expect("create the PNG"));
        let mut encoder = png::Encoder::new(file, self.width as u32, self.height as u32);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder
            .write_header()
            .expect("PNG header")
            .write_image_data(&self.rgb)
            .expect("PNG data");
    }
}

const GRASP: [u8; 3] = [255, 64, 64];
const CENTRE: [u8; 3] = [255, 220, 0];
const CHOSEN: [u8; 3] = [64, 200, 255];

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let save_scene = args
        .iter()
        .position(|a| a == "--save-scene")
        .and_then(|i| args.get(i + 1))
        .cloned();
    let out = args
        .first()
        .filter(|a| !a.starts_with("--"))
        .cloned()
        .unwrap_or_else(|| "target/demo.png".to_owned());
    let table = scene::grid_scene(0.0, 6, 3, 0.13);
    let camera = scene::Camera::orbit(Vector3::zeros(), 0.8, 50.0, -90.0);
    let rendered = scene::render(&table, &camera);
    let bytes = rendered.depth_bytes();
    let workspace = Workspace::new([-0.6, -0.4, -0.05], [0.6, 0.4, 0.4]).expect("workspace");
    let input = camera.scene_input(&bytes, workspace);
    if let Some(dir) = &save_scene {
        save_sample_scene(dir, &camera, &rendered.depth_mm, &workspace);
    }
    let mut net = MomentsNet::default();
    let planner = Planner::new(PlannerConfig::default(), net.contract().clone()).expect("planner");
    let options = PlanOptions {
        keep_views: true,
        max_grasps: 12,
        ..PlanOptions::default()
    };
    let plan = planner.plan(&input, &options, &mut net).expect("plan");

    println!(
        "table: normal {:.3?}, {:.1}% of the sample on it",
        plan.table.normal.as_slice(),
        100.0 * plan.table.support
    );
    println!("\nobject  centroid (m)               size (cm)            entropy top/front/side  chosen");
    for o in &plan.objects {
        let c = o.frame.world_from_object.translation.vector;
        let size = (o.frame.extent_max_m - o.frame.extent_min_m) * 100.0;
        let h: Vec<String> = o.views.iter().map(|v| format!("{:.2}", v.entropy)).collect();
        let chosen: Vec<&str> = o
            .views
            .iter()
            .filter(|v| v.inferred)
            .map(|v| v.axis.name())
            .collect();
        println!(
            "{:>6}  ({:+.3}, {:+.3}, {:+.3})  {:4.1} x {:4.1} x {:4.1}   {:<22}  {}",
            o.id,
            c.x,
            c.y,
            c.z,
            size.x,
            size.y,
            size.z,
            h.join(" / "),
            chosen.join(",")
        );
    }
    println!("\nrank  object  view   quality  width (mm)  centre (m)                 approach");
    for (rank, g) in plan.grasps.iter().enumerate() {
        let p = g.world_from_grasp.translation.vector;
        let a = g.world_from_grasp.rotation * Vector3::z();
        println!(
            "{:>4}  {:>6}  {:<5}  {:.3}    {:6.1}      ({:+.3}, {:+.3}, {:+.3})   ({:+.2}, {:+.2}, {:+.2})",
            rank + 1,
            g.object_id,
            g.view.name(),
            g.quality,
            g.width_m * 1000.0,
            p.x,
            p.y,
            p.z,
            a.x,
            a.y,
            a.z
        );
    }
    let t = plan.timings;
    println!(
        "\nstages (ms): sensor {:.2}, table {:.2}, objects {:.2}, cluster {:.2}, frames {:.2}, views {:.2}, select {:.2}, network {:.2}, decode {:.2}; all but the network {:.2}",
        ms(t.sensor),
        ms(t.table),
        ms(t.sensor_objects),
        ms(t.cluster),
        ms(t.frames),
        ms(t.views),
        ms(t.select),
        ms(t.inference),
        ms(t.decode),
        ms(t.without_inference())
    );

    // Left: the depth image, grasps drawn as finger-to-finger segments.
    let (w, h) = (camera.width as usize, camera.height as usize);
    let l = planner.contract().input_size_px;
    let scale = 2;
    let panel = l * scale + 8;
    let mut canvas = Canvas::new(w + 8 + 3 * panel, h.max(plan.objects.len() * panel));
    let valid: Vec<u16> = rendered.depth_mm.iter().copied().filter(|&d| d > 0).collect();
    let (lo, hi) = (
        *valid.iter().min().unwrap_or(&0),
        *valid.iter().max().unwrap_or(&1),
    );
    for (i, &d) in rendered.depth_mm.iter().enumerate() {
        let g = if d == 0 {
            0
        } else {
            255 - (f64::from(d - lo) / f64::from((hi - lo).max(1)) * 200.0) as u8
        };
        canvas.put((i % w) as i64, (i / w) as i64, [g, g, g]);
    }
    let to_pixel = |p: Vector3<f64>| {
        let c = camera.world_from_camera.inverse_transform_point(&Point3::from(p));
        camera.intrinsics.project(&c).map(|(u, v, _)| (u, v))
    };
    for g in plan.grasps.iter().rev() {
        let centre = g.world_from_grasp.translation.vector;
        let closing = g.world_from_grasp.rotation * Vector3::x();
        let ends = [
            centre - 0.5 * g.width_m * closing,
            centre + 0.5 * g.width_m * closing,
        ];
        if let (Some(a), Some(b), Some(c)) = (to_pixel(ends[0]), to_pixel(ends[1]), to_pixel(centre)) {
            canvas.line(a, b, GRASP);
            canvas.line((c.0 - 2.0, c.1), (c.0 + 2.0, c.1), CENTRE);
        }
    }
    // Right: per object, its three views (2x), the chosen one framed, its grasp drawn.
    for (row, object) in plan.objects.iter().enumerate() {
        for (col, dv) in plan
            .debug_views
            .iter()
            .filter(|d| d.object_id == object.id)
            .enumerate()
        {
            let (x0, y0) = (w + 8 + col * panel, row * panel);
            for (i, &value) in dv.view.image.iter().enumerate() {
                let g = (value * 255.0) as u8;
                for (sx, sy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    canvas.put(
                        (x0 + (i % l) * scale + sx) as i64,
                        (y0 + (i / l) * scale + sy) as i64,
                        [g, g, g],
                    );
                }
            }
            if dv.maps.is_some() {
                canvas.rect(x0, y0, l * scale, l * scale, CHOSEN);
            }
            for g in plan
                .grasps
                .iter()
                .filter(|g| g.object_id == object.id && g.view == dv.view.axis)
            {
                let (u, v) = (f64::from(g.pixel[0]) + 0.5, f64::from(g.pixel[1]) + 0.5);
                let half_px = 0.5 * g.width_m / f64::from(dv.view.pixel_size_m);
                let (c, s) = (f64::from(g.angle_rad).cos(), f64::from(g.angle_rad).sin());
                let at = |t: f64| {
                    (
                        x0 as f64 + (u + t * c) * scale as f64,
                        y0 as f64 + (v + t * s) * scale as f64,
                    )
                };
                canvas.line(at(-half_px), at(half_px), GRASP);
            }
        }
    }
    canvas.save(&out);
    println!("wrote {out}");
}

/// Writes `depth.png` (16-bit grey, millimetres) and `camera.json`.
fn save_sample_scene(dir: &str, camera: &scene::Camera, depth_mm: &[u16], workspace: &Workspace) {
    std::fs::create_dir_all(dir).expect("scene folder");
    let file = BufWriter::new(File::create(format!("{dir}/depth.png")).expect("depth.png"));
    let mut encoder = png::Encoder::new(file, camera.width, camera.height);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    let big_endian: Vec<u8> = depth_mm.iter().flat_map(|d| d.to_be_bytes()).collect(); // PNG is big-endian
    encoder
        .write_header()
        .expect("PNG header")
        .write_image_data(&big_endian)
        .expect("PNG data");
    let (k, pose) = (camera.intrinsics, camera.world_from_camera);
    let (p, q) = (pose.translation.vector, pose.rotation);
    let json = format!(
        "{{\n  \"width\": {}, \"height\": {},\n  \"intrinsics\": {{ \"fx\": {}, \"fy\": {}, \"cx\": {}, \"cy\": {} }},\n  \"world_from_camera\": {{ \"position\": [{}, {}, {}], \"orientation\": [{}, {}, {}, {}] }},\n  \"workspace\": {{ \"min\": [{}, {}, {}], \"max\": [{}, {}, {}] }}\n}}\n",
        camera.width,
        camera.height,
        k.fx,
        k.fy,
        k.cx,
        k.cy,
        p.x,
        p.y,
        p.z,
        q.i,
        q.j,
        q.k,
        q.w,
        workspace.min.x,
        workspace.min.y,
        workspace.min.z,
        workspace.max.x,
        workspace.max.y,
        workspace.max.z
    );
    std::fs::write(format!("{dir}/camera.json"), json).expect("camera.json");
    println!("wrote {dir}/depth.png and {dir}/camera.json");
}

fn ms(d: std::time::Duration) -> f64 {
    d.as_secs_f64() * 1e3
}
