//! Times `RadiusSearch::nearest` and `nearest_near` (with the previous answer as hint) on
//! one thread:
//! `cargo bench -p ggs --features internals --bench radius_probe -- SOURCE TARGET CELL R [SHIFT]`
//! (both clouds thinned to one point per cell of `CELL`; the queries are the source points
//! moved by `SHIFT · (1, −0.6, 0.8)`; every hinted answer is checked against the plain one).
mod common;

use ggs::refine::grid::RadiusSearch;
use std::time::Instant;

fn main() {
    let a: Vec<String> = common::args().collect();
    let read = |p: &str| {
        ggs::io::read_cloud(p.as_ref(), None)
            .unwrap()
            .cloud
            .to_points()
    };
    let cell: f64 = a[3].parse().unwrap();
    let r: f64 = a[4].parse().unwrap();
    let shift: f64 = a.get(5).map_or(0.0, |v| v.parse().unwrap());
    let src: Vec<_> = ggs::thin::cell_centroids(&read(&a[1]), cell)
        .into_iter()
        .map(|p| [p[0] + shift, p[1] - 0.6 * shift, p[2] + 0.8 * shift])
        .collect();
    let tgt = ggs::thin::cell_centroids(&read(&a[2]), cell);
    let search = RadiusSearch::new(&tgt, r, None);
    let mut found = vec![None; src.len()];
    let best = |f: &mut dyn FnMut()| {
        (0..7)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let plain = best(&mut || {
        for (q, f) in src.iter().zip(found.iter_mut()) {
            *f = search.nearest(q);
        }
    });
    let hits = found.iter().filter(|f| f.is_some()).count();
    let mut again = vec![None; src.len()];
    let hinted = best(&mut || {
        for ((q, f), g) in src.iter().zip(&found).zip(again.iter_mut()) {
            *g = search.nearest_near(q, f.map(|(j, _)| &tgt[j]));
        }
    });
    assert_eq!(found, again);
    println!(
        "{} queries, {} targets, {hits} found: nearest {:.1} ns, nearest_near {:.1} ns a query",
        src.len(),
        tgt.len(),
        plain / src.len() as f64 * 1e9,
        hinted / src.len() as f64 * 1e9
    );
}
