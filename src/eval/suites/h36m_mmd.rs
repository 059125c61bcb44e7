//! `glocal eval --suite h36m-mmd`: the paper's Human3.6M table, MMD_avg and MMD_seq of the
//! 2D front view of 50 predicted frames against the true continuations, per class.

use std::sync::Arc;

use anyhow::{bail, Context, Result};
use glam::Vec3;
use serde_json::{json, Value};

use super::context::SuiteContext;
use crate::data::expmap::front_view_2d;
use crate::data::registry::{self, Dataset, Split};
use crate::eval::metrics;
use crate::eval::table::{fixed as f, Markdown, Table};
use crate::model::glocal::GlocalModel;
use crate::motion::{Motion, Skeleton};

const MMD_WINDOWS_PER_CLASS: usize = 64;

fn every_nth(m: &Motion, n: usize) -> Motion {
    let positions: Vec<Vec3> = (0..m.frames()).step_by(n).flat_map(|t| m.frame(t).to_vec()).collect();
    Motion::from_positions(m.skeleton.clone(), m.fps / n as f32, positions)
}

/// 2D front view of frames (on the model's skeleton) at the 15 major joints, in meters.
fn view2d(skeleton: &Arc<Skeleton>, frames: Vec<Vec3>, joints: &[usize], hips: (usize, usize), unit: f32) -> Vec<f32> {
    let m = Motion::from_positions(skeleton.clone(), 1.0, frames);
    front_view_2d(&m, joints, hips.0, hips.1).into_iter().flat_map(|p| [p[0] * unit, p[1] * unit]).collect()
}

pub(super) fn run(ctx: &SuiteContext, log: &mut dyn FnMut(&str)) -> Result<(Markdown, Value)> {
    let (opts, join_seams) = (&ctx.options, ctx.generation.join_seams);
    let dir = ctx.model_dir(Dataset::H36m);
    let model = GlocalModel::load(&dir)?;
    let spec = model.spec.clone();
    let format = registry::expmap_format(Dataset::H36m, &opts.data)?;
    let major15 = format.major15.clone().context("h36m-skeleton.json has no major15")?;
    let model_joints: Vec<usize> = major15
        .iter()
        .map(|s| spec.source_joints.iter().position(|j| j == s).with_context(|| format!("major15 joint {s} is not among the model's joints")))
        .collect::<Result<_>>()?;
    let names = &spec.source_skeleton.names();
    let find = |n: &str| names.iter().position(|x| x == n).and_then(|s| spec.source_joints.iter().position(|j| *j == s));
    let hips = (find("LeftUpLeg").context("no LeftUpLeg")?, find("RightUpLeg").context("no RightUpLeg")?);
    log("h36m-mmd: loading h36m");
    let loaded = registry::load_archive(Dataset::H36m, &opts.data)?;
    let unit = spec.source_skeleton.meters_per_unit();
    let skel = spec.layout.skeleton.clone();
    let (s, t) = (spec.stride, spec.block_len);
    let (n_in, n_out) = (10usize, 50usize);
    let dt16 = 3.0 / 50.0;
    let blocks = ((n_out as f32 * dt16 * spec.fps / s as f32) / t as f32).ceil() as usize;
    let k = spec.classes.len();
    let mut per_class: Vec<Value> = Vec::new();
    let methods = ["GlocalNet (GloGen + LocGen, shipped model)", "GloGen + interpolation", "Zero-velocity"];
    let mut sums = vec![(0.0f64, 0.0f64); methods.len() + 1];
    // Mean 2D joint distance (m) to the true continuation, over windows, frames and joints.
    let mut errors = vec![0.0f64; methods.len()];
    for class in 0..k {
        let name = &spec.classes[class];
        let src_class = loaded.class_index(name).with_context(|| format!("h36m has no class {name}"))?;
        let mut real = Vec::new();
        let mut gens: Vec<Vec<Vec<f32>>> = vec![Vec::new(); methods.len()];
        let mut windows = Vec::new();
        for clip in loaded.split(Split::Test).filter(|c| c.class == src_class) {
            let mut m50 = clip.motion.subset(&spec.source_joints);
            m50.skeleton = skel.clone();
            let m25 = every_nth(&m50, 2);
            let m16 = every_nth(&m50, 3);
            // Window w: 16-fps frames w..w+60; the last observed one (w + 9) is 50-fps frame
            // 3(w + 9), a 25-fps frame when w + 9 is even.
            let mut w = 1;
            while w + n_in + n_out <= m16.frames() {
                let t0 = 3 * (w + n_in - 1) / 2;
                if t0 >= t * s + s && t0 < m25.frames() {
                    windows.push((m25.clone(), m16.clone(), w, t0));
                }
                w += 10;
            }
        }
        let step = (windows.len() as f64 / MMD_WINDOWS_PER_CLASS as f64).max(1.0);
        let picked: Vec<usize> = (0..).map(|i| (i as f64 * step) as usize).take_while(|&i| i < windows.len()).collect();
        for &i in &picked {
            let (m25, m16, w, t0) = &windows[i];
            let truth: Vec<Vec3> = (0..n_out).flat_map(|k| m16.frame(w + n_in + k).to_vec()).collect();
            real.push(view2d(&skel, truth, &model_joints, hips, unit));
            let observed = m25.frame(*t0).to_vec();
            let keys: Vec<Vec3> = observed.iter().copied().chain(model.forecast(m25, *t0, class, blocks, join_seams)?).collect();
            for (mi, locgen) in [(0, true), (1, false)] {
                let dense = model.densify(&keys, locgen);
                let frames: Vec<Vec3> = (1..=n_out).flat_map(|k| metrics::pose_at(&dense, skel.len(), spec.fps, k as f32 * dt16)).collect();
                gens[mi].push(view2d(&skel, frames, &model_joints, hips, unit));
            }
            let still: Vec<Vec3> = (0..n_out).flat_map(|_| observed.clone()).collect();
            gens[2].push(view2d(&skel, still, &model_joints, hips, unit));
            let truth = real.last().expect("pushed above");
            for (mi, g) in gens.iter().enumerate() {
                let g = g.last().expect("pushed above");
                let e: f64 = truth.chunks_exact(2).zip(g.chunks_exact(2)).map(|(a, b)| (((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)) as f64).sqrt()).sum::<f64>();
                errors[mi] += e / (truth.len() / 2) as f64 / (picked.len() * k) as f64;
            }
        }
        if real.len() < 4 {
            bail!("h36m {name}: only {} test windows", real.len());
        }
        // Reference: the first half of the real windows (in take and time order: mostly
        // the first S11 take) against the second half.
        let half = real.len() / 2;
        let (ra, rb) = (real[..half].to_vec(), real[half..2 * half].to_vec());
        let mut row = json!({"class": name, "windows": real.len()});
        for (mi, label) in methods.iter().enumerate() {
            let (a, sq) = metrics::mmd_avg_seq(&real, &gens[mi], 30);
            sums[mi].0 += a / k as f64;
            sums[mi].1 += sq / k as f64;
            row[*label] = json!({"mmd_avg": a, "mmd_seq": sq});
        }
        let (a, sq) = metrics::mmd_avg_seq(&ra, &rb, 30);
        sums[methods.len()].0 += a / k as f64;
        sums[methods.len()].1 += sq / k as f64;
        row["real vs real (first vs second half)"] = json!({"mmd_avg": a, "mmd_seq": sq});
        log(&format!("h36m-mmd {name}: {} windows", real.len()));
        per_class.push(row);
    }
    let mut md = Markdown::new(
        "Human3.6M, 2D front view of the 15 major joints (meters, root-relative), 16.7 fps (every third 50-fps frame), 50 predicted frames per test window of subject S11, up to 64 windows per class, 10 classes. MMD is the unbiased estimate of MMD² (Gaussian kernel, maximum over bandwidths 1e-4..1e9), per class then averaged. Our model observes the 2 s before the first predicted frame (10 sparse poses at 5 Hz, its own block), not the 10 frames at 16 fps of the published protocol: the published rows are printed for reference and are not directly comparable.\n\n",
    );
    let mut table = Table::new(["method", "MMD_avg", "MMD_seq", "mean 2D distance to the true continuation (m)"]);
    let mut summary = Vec::new();
    for (mi, label) in methods.iter().chain(std::iter::once(&"Real vs real (first vs second half of the S11 windows, reference)")).enumerate() {
        let e = errors.get(mi).copied().unwrap_or(f64::NAN);
        table.row([label.to_string(), f(sums[mi].0, 3), f(sums[mi].1, 3), f(e, 3)]);
        summary.push(json!({"method": label, "mmd_avg": sums[mi].0, "mmd_seq": sums[mi].1, "mean_2d_error_m": e}));
    }
    for (label, a, sq) in [("SA-GCN (published)", 0.146, 0.134), ("GlocalNet (published)", 0.103, 0.102)] {
        table.row([format!("*{label}, not directly comparable*"), format!("{a:.3}"), format!("{sq:.3}")]);
    }
    md.table(table);
    Ok((md, json!({"model": dir, "summary": summary, "per_class": per_class})))
}
