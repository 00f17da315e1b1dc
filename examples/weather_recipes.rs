//! Multi-rule weathering recipes transferred between shared meshes, scored against the recipe
//! applied to the target, with a k-nearest-neighbour regression on the recipe's features beside.
//!
//! `cargo run --release --example weather_recipes [-- --ablate] [--diagnose]`; `N` sets the
//! working vertices (default 50000), `PAIRS` the pairs (`igea:bunny,cow:cat,nefertiti:penguin`),
//! `RECIPES` the recipes by name, `VARIANTS` parameter variants beside the defaults (`np`,
//! `dims1`, `dims2`, `noms`, `nomatch`, `half`, `noise0`, `noise05`, `k1`, `k10`, `k200`, `nb1`,
//! `nb2`, `nohb`, `hb1`, `lv1`, `lv2`, `affine`; combined with `+`, e.g. `affine+nomatch`). `CAP=1`
//! also prints each recipe without its grain scored against the recipe with it: the most a
//! result that keeps the grain can reach. `OUT=dir` writes the target coloured by the recipe
//! (`{source}_{target}_{recipe}_truth.ply`) and by each variant's result.

use meshmatch::synthesis::weathering::recipes::{
    Recipe, Rule, diagnose, evaluate, prepare, recipes,
};
use meshmatch::synthesis::weathering::{Method, Params, Up};
use meshmatch::testdata::data_path;
use meshmatch::work::CancelToken;

fn file(name: &str) -> String {
    match name {
        "cow" => "cow/cow.ply".into(),
        "horse" => "horse/horse.ply".into(),
        "igea" => "igea/igea.ply".into(),
        "spot" => "spot/spot.obj".into(),
        other => format!("{other}/{other}.obj"),
    }
}

fn load(name: &str) -> meshmatch::TriMesh {
    let mut m = meshmatch::mesh::io::load(&data_path(&file(name))).expect("load");
    m.repair().expect("repair");
    m
}

fn row(label: &str, s: &meshmatch::synthesis::weathering::recipes::Scores) -> String {
    format!(
        "{label:<8} L {:>5.2}  a {:>5.2}  b {:>5.2}  W1 {:>5.2}  grain {:>4.2}",
        s.corr[0], s.corr[1], s.corr[2], s.w1, s.grain
    )
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let ablate = args.iter().any(|a| a == "--ablate");
    let diag = args.iter().any(|a| a == "--diagnose");
    let n: usize = std::env::var("N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(50_000);
    let pairs = std::env::var("PAIRS").unwrap_or("igea:bunny,cow:cat,nefertiti:penguin".into());
    let mut list: Vec<Recipe> = recipes();
    if ablate {
        list = Rule::ALL.iter().map(|&r| Recipe::single(r)).collect();
        list.push(Recipe::new("all", &Rule::ALL));
    }
    if let Ok(only) = std::env::var("RECIPES") {
        list.retain(|r| only.split(',').any(|n| n == r.name));
    }
    let mut variants: Vec<(&str, Params)> = vec![("default", Params::default())];
    if let Ok(v) = std::env::var("VARIANTS") {
        for name in v.split(',') {
            // modifiers compose with '+', e.g. `nomatch+noise0`
            let mut p = Params::default();
            let mut known = true;
            for m in name.split('+') {
                match m {
                    "np" => p.method = Method::NonParametric,
                    "dims1" => p.cca_dims = 1,
                    "dims2" => p.cca_dims = 2,
                    "noms" => p.multiscale_matching = false,
                    "nomatch" => p.match_strength = 0.0,
                    "half" => p.match_strength = 0.5,
                    "noise0" => p.noise = 0.0,
                    "noise05" => p.noise = 0.5,
                    "k1" => p.clusters = 1,
                    "k10" => p.clusters = 10,
                    "k200" => p.clusters = 200,
                    "nb1" => p.neighbours = 1,
                    "nb2" => p.neighbours = 2,
                    "nohb" => p.hb_iterations = 0,
                    "affine" => p.mean = meshmatch::synthesis::weathering::Mean::Affine,
                    "hb1" => p.hb_iterations = 1,
                    "lv1" => p.levels = 1,
                    "lv2" => p.levels = 2,
                    _ => known = false,
                }
            }
            if known {
                variants.push((Box::leak(name.to_string().into_boxed_str()), p));
            }
        }
    }
    let cancel = CancelToken::new();
    for pair in pairs.split(',') {
        let (s, t) = pair.split_once(':').expect("source:target");
        let pr = prepare(&load(s), &load(t), n, Up::Y, &cancel).expect("prepare");
        println!(
            "== {s} -> {t} ({} / {} points)",
            pr.source.num_vertices(),
            pr.target_refined.num_vertices()
        );
        if args.iter().any(|a| a == "--coverage") {
            use meshmatch::synthesis::weathering::recipes::rule_strength;
            for (what, fs) in [
                ("source", &pr.source_features),
                ("target", &pr.target_features),
            ] {
                let mut line = format!("{what:<8} coverage");
                for rule in Rule::ALL {
                    let v: Vec<f32> = (0..fs.len())
                        .map(|i| rule_strength(rule, fs, i, Up::Y))
                        .collect();
                    let mean = v.iter().sum::<f32>() / v.len() as f32;
                    let over = v.iter().filter(|&&x| x > 0.5).count() as f32 / v.len() as f32;
                    line += &format!("  {} {mean:.2}/{over:.2}", rule.name());
                }
                println!("{line}");
                for (name, c) in [
                    ("height", 0),
                    ("normal-y", 2),
                    ("curv0", 4),
                    ("curv1", 5),
                    ("ao", 8),
                ] {
                    let mut v: Vec<f32> =
                        fs.values.iter().skip(c).step_by(fs.dim).copied().collect();
                    v.sort_by(f32::total_cmp);
                    let q = |f: f32| v[((v.len() - 1) as f32 * f) as usize];
                    println!(
                        "  {name:<9} 1% {:.3} 10% {:.3} 50% {:.3} 90% {:.3} 99% {:.3}",
                        q(0.01),
                        q(0.1),
                        q(0.5),
                        q(0.9),
                        q(0.99)
                    );
                }
            }
            continue;
        }
        for r in &list {
            if std::env::var("CAP").is_ok() {
                use meshmatch::synthesis::weathering::recipes::{paint, score};
                let t = paint(r, &pr.target_features, &pr.target_refined.positions, Up::Y);
                let mut r0 = r.clone();
                r0.grain = 0.0;
                let t0 = paint(
                    &r0,
                    &pr.target_features,
                    &pr.target_refined.positions,
                    Up::Y,
                );
                let adj = pr.target_refined.adjacency();
                println!(
                    "{:<8} cap(nograin vs truth) {}",
                    r.name,
                    row("", &score(&t0, &t, &adj))
                );
            }
            let out = std::env::var("OUT").ok().map(std::path::PathBuf::from);
            let write = |what: &str, colours: Vec<[f32; 3]>| {
                if let Some(dir) = &out {
                    let mut m = pr.target_refined.clone();
                    m.colors = Some(colours);
                    let path = dir.join(format!("{s}_{t}_{}_{what}.ply", r.name));
                    meshmatch::mesh::io::save(&m, &path).expect("save");
                }
            };
            if out.is_some() {
                use meshmatch::synthesis::weathering::recipes::paint;
                write(
                    "truth",
                    paint(r, &pr.target_features, &pr.target_refined.positions, Up::Y),
                );
            }
            for (vname, params) in &variants {
                let e = evaluate(&pr, r, params, &cancel).expect("evaluate");
                write(vname, e.colors.clone());
                println!(
                    "{:<8} {:<8} {}   | knn {}  ({:.1} s, rho {:.2?})",
                    r.name,
                    vname,
                    row("", &e.method),
                    row("", &e.knn),
                    e.seconds,
                    e.correlations
                );
            }
            if diag {
                let [all, raw, matched] = diagnose(&pr, r, 3).expect("diagnose");
                println!("{:<8} diag     {}", r.name, row("knn12", &all));
                println!("{:<8} diag     {}", r.name, row("knncca", &raw));
                println!("{:<8} diag     {}", r.name, row("knnpdf", &matched));
            }
        }
    }
}
