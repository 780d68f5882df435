//! Videos of a walk: MuJoCo renders the run offscreen (EGL, headless), a camera follows the
//! trunk, a line of text shows time and commanded against measured velocity, and the frames
//! become an animated GIF (the `gif` crate of image-rs: pure Rust, nothing to install; no
//! MP4 encoder is available on these machines without a system ffmpeg).

use eemp_core::body_state::{BodyState, LegJointState, RobotState};
use eemp_core::leg::{Leg, LegMap};
use eemp_core::robot::RobotConfig;
use eemp_sim::mjcf::SceneExtras;
use eemp_sim::Simulation;
use mujoco_rs::prelude::MjtObjBase;
use mujoco_rs::renderer::MjRenderer;
use mujoco_rs::wrappers::mj_visualization::MjvCamera;
use nalgebra::{UnitQuaternion, Vector3};
use plotters::prelude::*;
use std::path::Path;

/// Frames per second of the videos.
pub const FPS: f64 = 25.0;
const WIDTH: usize = 480;
const HEIGHT: usize = 320;

/// What one frame shows.
#[derive(Clone, Debug)]
pub struct VideoFrame {
    pub t_s: f64,
    pub p_world: Vector3<f64>,
    pub rpy: Vector3<f64>,
    pub q: LegMap<Vector3<f64>>,
    /// Commanded and measured forward and lateral velocity (heading frame), m/s.
    pub cmd: [f64; 2],
    pub measured: [f64; 2],
}

impl VideoFrame {
    pub fn of(state: &RobotState, cmd: [f64; 2]) -> Self {
        let v = state.body.v_heading();
        VideoFrame {
            t_s: state.time_s,
            p_world: state.body.p_world,
            rpy: state.body.rpy(),
            q: state.joints.map(|_, j| j.q),
            cmd,
            measured: [v.x, v.y],
        }
    }
}

/// Renders `frames` into an animated GIF at `path`, and its middle frame (without the text)
/// as a PNG beside it.
pub fn write_gif(
    robot: &RobotConfig,
    scene: &SceneExtras,
    frames: &[VideoFrame],
    label: &str,
    path: &Path,
) -> Result<(), String> {
    if frames.is_empty() {
        return Err("no frames to render".into());
    }
    let mut sim = Simulation::new(robot, scene).map_err(|e| e.to_string())?;
    let model = sim.model();
    let trunk = model
        .name_to_id(MjtObjBase::mjOBJ_BODY, "trunk")
        .ok_or("the model has no trunk body")?;
    let mut camera = MjvCamera::new_tracking(trunk);
    camera.distance = 1.3;
    camera.azimuth = 135.0;
    camera.elevation = -20.0;
    let mut renderer = MjRenderer::new(&model, WIDTH, HEIGHT, 0)
        .map_err(|e| format!("cannot render offscreen (EGL): {e}"))?
        .with_camera(camera);
    let file =
        std::fs::File::create(path).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    let mut enc = gif::Encoder::new(file, WIDTH as u16, HEIGHT as u16, &[])
        .map_err(|e| format!("{}: {e}", path.display()))?;
    enc.set_repeat(gif::Repeat::Infinite)
        .map_err(|e| e.to_string())?;
    let poster = frames.len() / 2;
    // The renderer (its GL context) stays on this thread; the overlay, the palette and the
    // encoding of each frame run on a second one, overlapping the next frame's rendering.
    let (tx, rx) = std::sync::mpsc::sync_channel::<(Vec<u8>, &VideoFrame)>(4);
    std::thread::scope(|scope| {
        let encoder = scope.spawn(move || -> Result<(), String> {
            for (mut rgb, f) in rx {
                overlay(&mut rgb, label, f).map_err(|e| e.to_string())?;
                let mut frame = gif::Frame::from_rgb_speed(WIDTH as u16, HEIGHT as u16, &rgb, 20);
                frame.delay = (100.0 / FPS).round() as u16;
                enc.write_frame(&frame).map_err(|e| e.to_string())?;
            }
            Ok(())
        });
        for (k, f) in frames.iter().enumerate() {
            let state = RobotState {
                time_s: f.t_s,
                body: BodyState {
                    p_world: f.p_world,
                    r_world_body: UnitQuaternion::from_euler_angles(f.rpy.x, f.rpy.y, f.rpy.z),
                    v_world: Vector3::zeros(),
                    omega_world: Vector3::zeros(),
                },
                joints: LegMap::from_fn(|l: Leg| LegJointState {
                    q: f.q[l],
                    qd: Vector3::zeros(),
                }),
            };
            sim.set_state(&state);
            renderer
                .sync_data(sim.data_mut())
                .map_err(|e| e.to_string())?;
            renderer.render().map_err(|e| e.to_string())?;
            if k == poster {
                // A still beside the video (for pages that show no animation).
                renderer
                    .save_rgb(path.with_extension("png"))
                    .map_err(|e| e.to_string())?;
            }
            // (mujoco-rs returns the rows top-down already.)
            let img = renderer.rgb_flat().ok_or("RGB rendering is off")?;
            if tx.send((img.to_vec(), f)).is_err() {
                break; // the encoder stopped: its error is reported below
            }
        }
        drop(tx);
        encoder
            .join()
            .map_err(|_| "the GIF encoder panicked".to_string())?
    })
}

fn overlay(rgb: &mut [u8], label: &str, f: &VideoFrame) -> Result<(), Box<dyn std::error::Error>> {
    crate::plots::ensure_font()?;
    let root = BitMapBackend::with_buffer(rgb, (WIDTH as u32, HEIGHT as u32)).into_drawing_area();
    root.draw(&Rectangle::new(
        [(0, 0), (WIDTH as i32, 44)],
        WHITE.mix(0.75).filled(),
    ))?;
    let style = ("sans-serif", 15).into_font().color(&BLACK);
    root.draw_text(&format!("{label}   t = {:.1} s", f.t_s), &style, (6, 4))?;
    root.draw_text(
        &format!(
            "commanded vx {:+.2} vy {:+.2} m/s   measured vx {:+.2} vy {:+.2} m/s",
            f.cmd[0], f.cmd[1], f.measured[0], f.measured[1]
        ),
        &style,
        (6, 24),
    )?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The GIF holds what MuJoCo rendered (not flipped, overlay on top): decode it back and
    /// compare a frame's lower half with the still of the same frame.
    #[test]
    fn the_gif_frames_are_the_rendered_images_with_the_overlay_on_top() {
        let robot = RobotConfig::a1();
        let q = robot.standing_pose();
        let f = VideoFrame {
            t_s: 0.0,
            p_world: Vector3::new(0.0, 0.0, 0.3),
            rpy: Vector3::zeros(),
            q,
            cmd: [0.3, 0.0],
            measured: [0.29, 0.01],
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("v.gif");
        if let Err(e) = write_gif(
            &robot,
            &SceneExtras::default(),
            &[f.clone(), f],
            "test",
            &path,
        ) {
            // No EGL on this machine: say so instead of failing the suite on a missing GPU stack.
            assert!(e.contains("EGL"), "{e}");
            eprintln!("skipped: {e}");
            return;
        }
        let mut opts = gif::DecodeOptions::new();
        opts.set_color_output(gif::ColorOutput::RGBA);
        let mut dec = opts.read_info(std::fs::File::open(&path).unwrap()).unwrap();
        let frame = dec.read_next_frame().unwrap().unwrap().clone();
        assert_eq!(
            (frame.width as usize, frame.height as usize),
            (WIDTH, HEIGHT)
        );
        assert_eq!(frame.delay, 4);
        let still = std::fs::read(path.with_extension("png")).unwrap();
        assert!(still.len() > 1000);
        // The camera looks down at the robot from behind: the dark robot and its shadow sit
        // in the lower half of the picture (upside down they would be in the upper half).
        let (mut sum_y, mut n) = (0.0, 0.0);
        for y in 44..HEIGHT - 40 {
            for x in 0..WIDTH {
                let p = &frame.buffer[(y * WIDTH + x) * 4..];
                if (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0 < 80.0 {
                    sum_y += y as f64;
                    n += 1.0;
                }
            }
        }
        assert!(n > 500.0, "the robot is in the picture ({n} dark pixels)");
        let centroid = sum_y / n;
        assert!(
            centroid > HEIGHT as f64 / 2.0,
            "robot centred at row {centroid}: flipped?"
        );
        // The overlay is a light band with dark text at the top.
        let band: f64 = (0..WIDTH)
            .map(|x| frame.buffer[(10 * WIDTH + x) * 4] as f64)
            .sum::<f64>()
            / WIDTH as f64;
        assert!(band > 150.0, "overlay band brightness {band}");
    }
}
