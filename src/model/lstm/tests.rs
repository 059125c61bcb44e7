//! The two paths against candle-nn's LSTM (outputs and gradients, under every [`Threading`]),
//! the frozen path against the training path, and the op's gradients against finite
//! differences.
use super::*;
use candle_core::{Device, Var};
use candle_nn::VarMap;

fn max_abs(a: &Tensor, b: &Tensor) -> f32 {
    (a - b).unwrap().abs().unwrap().flatten_all().unwrap().max(0).unwrap().to_scalar::<f32>().unwrap()
}

fn build(i: usize, h: usize, threading: Threading) -> (VarMap, BiLstm) {
    let vm = VarMap::new();
    let vb = VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu);
    let l = BiLstm::new(i, h, vb.pp("lstm")).unwrap();
    // non-zero biases everywhere (PyTorch-style init already gives that)
    (vm, BiLstm { threading, ..l })
}

#[test]
fn forward_matches_candle_nn() {
    for &(b, t, i, h) in &[(3usize, 7usize, 5usize, 6usize), (9, 10, 92, 40), (1, 4, 3, 17)] {
        for th in Threading::ALL {
            let (_vm, l) = build(i, h, th);
            let x = Tensor::randn(0f32, 1.0, (b, t, i), &Device::Cpu).unwrap();
            let fast = l.forward(&x).unwrap();
            let slow = l.forward_reference(&x).unwrap();
            assert_eq!(fast.dims(), &[b, t, 2 * h]);
            let dfwd = max_abs(&fast.narrow(2, 0, h).unwrap(), &slow.narrow(2, 0, h).unwrap());
            let dbwd = max_abs(&fast.narrow(2, h, h).unwrap(), &slow.narrow(2, h, h).unwrap());
            assert!(dfwd < 1e-4, "forward direction differs: {dfwd}");
            assert!(dbwd < 1e-4, "backward direction differs: {dbwd}");
        }
    }
}

#[test]
fn frozen_infer_matches_forward() {
    let shapes = [(1usize, 10usize, 12usize, 20usize), (2, 10, 12, 40), (3, 5, 7, 9), (16, 6, 10, 8)];
    for (&(b, t, i, h), th) in shapes.iter().flat_map(|s| Threading::ALL.map(|th| (s, th))) {
        let (_vm, l) = build(i, h, th);
        let x = Tensor::randn(0f32, 1.0, (b, t, i), &Device::Cpu).unwrap();
        let fast = l.forward(&x).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let frozen = l.freeze().unwrap();
        let xv = x.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let mut out = vec![0f32; b * t * 2 * h];
        let mut sc = Scratch::default();
        frozen.infer(&xv, b, t, &mut out, &mut sc);
        let d = fast.iter().zip(&out).map(|(a, b)| (a - b).abs()).fold(0f32, f32::max);
        assert!(d < 1e-5, "frozen differs by {d}");
        // second call on the same scratch gives the same
        let mut out2 = vec![0f32; b * t * 2 * h];
        frozen.infer(&xv, b, t, &mut out2, &mut sc);
        assert_eq!(out, out2);
    }
}

/// Loss = sum(out * r) through the fast op; its gradients w.r.t. the input and every parameter
/// (both directions' W_ih, W_hh, biases) vs central finite differences of the op's forward
/// (accumulated in f64).
#[test]
fn op_gradients_match_finite_differences() {
    let (b, t, i, h) = (2usize, 4usize, 3usize, 5usize);
    let fl = FlatLayout { i, h };
    let dev = Device::Cpu;
    let x = Var::from_tensor(&Tensor::randn(0f32, 1.0, (b * t, i), &dev).unwrap()).unwrap();
    let p = Var::from_tensor(&Tensor::randn(0f32, 0.5, fl.len(), &dev).unwrap()).unwrap();
    let r = Tensor::randn(0f32, 1.0, (b, t, 2 * h), &dev).unwrap();
    let rv = r.flatten_all().unwrap().to_vec1::<f32>().unwrap();
    let loss_of = |xv: &[f32], pv: &[f32]| -> f64 {
        let xt = Tensor::from_slice(xv, (b * t, i), &dev).unwrap();
        let pt = Tensor::from_slice(pv, fl.len(), &dev).unwrap();
        let o = xt.apply_op2_no_bwd(&pt, &BiLstmOp::new(b, t, i, h, Threading::default())).unwrap();
        let o = o.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        o.iter().zip(&rv).map(|(a, b)| *a as f64 * *b as f64).sum()
    };
    let out = x.as_tensor().apply_op2(p.as_tensor(), BiLstmOp::new(b, t, i, h, Threading::default())).unwrap();
    let loss = (out * &r).unwrap().sum_all().unwrap();
    let grads = loss.backward().unwrap();
    let gx = grads.get(x.as_tensor()).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
    let gp = grads.get(p.as_tensor()).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
    let xv = x.as_tensor().flatten_all().unwrap().to_vec1::<f32>().unwrap();
    let pv = p.as_tensor().flatten_all().unwrap().to_vec1::<f32>().unwrap();
    // five-point stencil: truncation error O(eps^4), f32 rounding noise ~1e-6 / eps
    let eps = 1e-2f32;
    let stencil = |f: &dyn Fn(f32) -> f64| -> f64 {
        (8.0 * (f(eps) - f(-eps)) - (f(2.0 * eps) - f(-2.0 * eps))) / (12.0 * eps as f64)
    };
    // relative error of the whole gradient block: |fd - analytic| / |fd| (2-norms)
    let rel = |fd: &[f64], an: &[f32]| -> f64 {
        let num: f64 = fd.iter().zip(an).map(|(a, b)| (a - *b as f64).powi(2)).sum();
        let den: f64 = fd.iter().map(|a| a * a).sum();
        (num / den).sqrt()
    };
    // the stencil of `loss` in each coordinate of `v`
    let finite_differences = |v: &[f32], loss: &dyn Fn(&[f32]) -> f64| -> Vec<f64> {
        (0..v.len())
            .map(|k| {
                stencil(&|e| {
                    let mut a = v.to_vec();
                    a[k] += e;
                    loss(&a)
                })
            })
            .collect()
    };
    let fd_x = finite_differences(&xv, &|a| loss_of(a, &pv));
    let fd_p = finite_differences(&pv, &|a| loss_of(&xv, a));
    let rx = rel(&fd_x, &gx);
    eprintln!("finite differences: input rel err {rx:.2e}");
    assert!(rx < 1e-3, "input gradient: finite-difference mismatch {rx}");
    // each parameter block separately: W_ih, W_hh, biases of each direction
    for (name, lo, hi) in [
        ("w_ih fwd", fl.w_ih(0), fl.w_ih(1)),
        ("w_ih bwd", fl.w_ih(1), fl.w_hh(0)),
        ("w_hh fwd", fl.w_hh(0), fl.w_hh(1)),
        ("w_hh bwd", fl.w_hh(1), fl.b_ih(0)),
        ("b_ih", fl.b_ih(0), fl.b_hh(0)),
        ("b_hh", fl.b_hh(0), fl.len()),
    ] {
        let r = rel(&fd_p[lo..hi], &gp[lo..hi]);
        eprintln!("finite differences: {name} rel err {r:.2e}");
        assert!(r < 1e-3, "{name} gradient: finite-difference mismatch {r}");
    }
    // not trivially zero, in every block of the parameters
    for (lo, hi) in [(fl.w_ih(0), fl.w_ih(1)), (fl.w_hh(1), fl.b_ih(0)), (fl.b_hh(1), fl.len())] {
        assert!(gp[lo..hi].iter().any(|v| v.abs() > 1e-3));
    }
    // without x in the graph, no input gradient is produced
    let xc = Tensor::from_slice(&xv, (b * t, i), &dev).unwrap();
    let l2 = (xc.apply_op2(p.as_tensor(), BiLstmOp::new(b, t, i, h, Threading::default())).unwrap() * &r).unwrap().sum_all().unwrap();
    let g2 = l2.backward().unwrap();
    assert!(g2.get(&xc).is_none());
    let gp2 = g2.get(p.as_tensor()).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
    assert_eq!(gp, gp2);
}

/// Same loss through the fast path and through candle-nn's LSTM; gradients w.r.t. all eight
/// weights and the input must agree.
#[test]
fn gradients_match_candle_nn_autograd() {
    for th in Threading::ALL {
        let (b, t, i, h) = (4usize, 6usize, 7usize, 9usize);
        let (_vm, l) = build(i, h, th);
        let x = Var::from_tensor(&Tensor::randn(0f32, 1.0, (b, t, i), &Device::Cpu).unwrap()).unwrap();
        let r = Tensor::randn(0f32, 1.0, (b, t, 2 * h), &Device::Cpu).unwrap();
        let lf = (l.forward(x.as_tensor()).unwrap() * &r).unwrap().sqr().unwrap().sum_all().unwrap();
        let lr = (l.forward_reference(x.as_tensor()).unwrap() * &r).unwrap().sqr().unwrap().sum_all().unwrap();
        let gf = lf.backward().unwrap();
        let gr = lr.backward().unwrap();
        for (k, p) in l.tensors().iter().enumerate() {
            let a = gf.get(p).expect("fast grad");
            let c = gr.get(p).expect("reference grad");
            let d = max_abs(a, c);
            let scale = c.abs().unwrap().flatten_all().unwrap().max(0).unwrap().to_scalar::<f32>().unwrap();
            assert!(d < 1e-4 * (1.0 + scale), "param {k}: grad diff {d} (scale {scale})");
        }
        let d = max_abs(gf.get(x.as_tensor()).unwrap(), gr.get(x.as_tensor()).unwrap());
        assert!(d < 1e-4, "input grad diff {d}");
    }
}
