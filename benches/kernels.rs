//! The cell kernels' cost per quadrature point: the static residual, and the residual with its
//! tangent, of three examples' models at a smooth deformation with a field, on the thread pool
//! (`RAYON_NUM_THREADS=1` for one thread).
//!
//! ```sh
//! RAYON_NUM_THREADS=1 cargo bench --bench kernels
//! RAYON_NUM_THREADS=1 cargo bench --bench kernels -- diaphragm-3d 20000   # residuals only, for perf
//! ```
//!
//! Cases: `diaphragm-3d` (mean-dilatation hex8, Yeoh), `film` 40 × 40 × 8 (standard hex8,
//! neo-Hooke), `diaphragm` (axisymmetric quad4, Yeoh). The state stretches each model by 2 %
//! along x, thins it by 1 % along z, and puts 1 kV per millimetre of z on it.

use deasim::algebra::system::NonlinearSystem;
use deasim::problem::statics::StaticProblem;
use std::time::Instant;

/// The best of this many evaluations is the figure.
const REPEATS: usize = 100;

fn model(name: &str) -> deasim::problem::model::Model {
    let sets = if name == "film" {
        vec!["mesh.divisions=[40, 40, 8]".to_string()]
    } else {
        Vec::new()
    };
    let text = deasim::io::examples::example(name).expect("an example");
    let s = deasim::io::scenario::parse(text, name, &sets).expect("its scenario");
    let plan = deasim::io::build::build(&s, name, None).expect("its plan");
    let mut model = plan.model.clone();
    model.dirichlet = plan.supports.clone();
    model
}

fn state(model: &deasim::problem::model::Model) -> Vec<f64> {
    let mut s = vec![0.0; model.mesh.n_nodes() * 4];
    for (i, x) in model.mesh.nodes.iter().enumerate() {
        s[4 * i] = 0.02 * x[0] + 1e-3 * x[1];
        s[4 * i + 1] = -0.005 * x[1];
        s[4 * i + 2] = -0.01 * x[2];
        s[4 * i + 3] = 1e6 * x[2];
    }
    s
}

fn main() {
    let mut args = std::env::args().skip(1).filter(|a| a != "--bench");
    let only = args.next();
    let loops: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(0);
    println!(
        "{} threads; ns per quadrature point, best of {REPEATS}",
        rayon::current_num_threads()
    );
    println!(
        "{:>14} {:>9} {:>10} {:>10}",
        "case", "points", "residual", "tangent"
    );
    for name in ["diaphragm-3d", "film", "diaphragm"] {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        let m = model(name);
        let s = state(&m);
        let mut points = 0usize;
        m.for_each_cell(&s, |_, g, _, _| {
            points += g.n_qp;
            Ok::<(), String>(())
        })
        .expect("the cells");
        let mut p = StaticProblem::new(&m, Some(s));
        let mut k = p.new_matrix();
        let mut r = vec![0.0; p.n()];
        if loops > 0 {
            for _ in 0..loops {
                p.evaluate(&mut r, None).expect("a residual");
            }
            continue;
        }
        let (mut res, mut tan) = (f64::INFINITY, f64::INFINITY);
        for _ in 0..REPEATS {
            let t = Instant::now();
            p.evaluate(&mut r, None).expect("a residual");
            res = res.min(t.elapsed().as_secs_f64());
            let t = Instant::now();
            p.evaluate(&mut r, Some(&mut k)).expect("a tangent");
            tan = tan.min(t.elapsed().as_secs_f64());
        }
        let per = 1e9 / points as f64;
        println!(
            "{name:>14} {points:>9} {:>10.1} {:>10.1}",
            res * per,
            tan * per
        );
    }
}
