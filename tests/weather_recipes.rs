//! Multi-rule weathering recipes (`synthesis::weathering::recipes`) transferred cow -> cat: each
//! rule alone and all together, scored against the recipe applied to the cat, beside a
//! k-nearest-neighbour regression on the recipe's own features.

use std::sync::OnceLock;

use meshmatch::synthesis::weathering::Params;
use meshmatch::synthesis::weathering::Up;
use meshmatch::synthesis::weathering::recipes::{
    Evaluation, Prepared, Recipe, Rule, evaluate, prepare,
};
use meshmatch::testdata::data_path;
use meshmatch::work::CancelToken;

fn pair() -> &'static Prepared {
    static PAIR: OnceLock<Prepared> = OnceLock::new();
    PAIR.get_or_init(|| {
        let load = |p: &str| {
            let mut m = meshmatch::mesh::io::load(&data_path(p)).unwrap();
            m.repair().unwrap();
            m
        };
        prepare(
            &load("cow/cow.ply"),
            &load("cat/cat.obj"),
            12_000,
            Up::Y,
            &CancelToken::new(),
        )
        .unwrap()
    })
}

fn run(recipe: &Recipe) -> Evaluation {
    let e = evaluate(pair(), recipe, &Params::default(), &CancelToken::new()).unwrap();
    eprintln!(
        "{}: L {:.2} a {:.2} b {:.2} W1 {:.2} grain {:.2} | knn L {:.2} a {:.2} b {:.2} W1 {:.2}",
        recipe.name,
        e.method.corr[0],
        e.method.corr[1],
        e.method.corr[2],
        e.method.w1,
        e.method.grain,
        e.knn.corr[0],
        e.knn.corr[1],
        e.knn.corr[2],
        e.knn.w1
    );
    e
}

/// Lightness follows the recipe at least `l`, the distribution is within `w1` Lab units, and the
/// grain is kept within a factor of two.
fn check(e: &Evaluation, l: f64, w1: f64) {
    assert!(e.method.corr[0] > l, "lightness {:.3}", e.method.corr[0]);
    assert!(e.method.w1 < w1, "W1 {:.3}", e.method.w1);
    assert!(
        (0.5..2.0).contains(&e.method.grain),
        "grain {:.3}",
        e.method.grain
    );
}

#[test]
fn dirt_alone() {
    check(&run(&Recipe::single(Rule::Dirt)), 0.8, 4.0);
}

#[test]
fn edge_wear_alone() {
    check(&run(&Recipe::single(Rule::Wear)), 0.8, 4.0);
}

/// Measured 0.79 at 12K points (kNN floor 0.76; the paper's affine mean 0.38).
#[test]
fn concavity_alone() {
    let e = run(&Recipe::single(Rule::Concavity));
    check(&e, 0.7, 4.0);
    assert!(
        e.method.corr[1] > 0.7 && e.method.corr[2] > 0.7,
        "{:?}",
        e.method.corr
    );
}

#[test]
fn height_tint_alone() {
    check(&run(&Recipe::single(Rule::HeightTint)), 0.8, 4.0);
}

/// Measured L 0.61, a* 0.78 at 12K points (kNN floor 0.62, 0.82; the paper's affine mean 0.51,
/// 0.63). Moss changes lightness little, so its lightness correlation stays below 0.7 (the
/// recipe without grain against with it: 0.81).
#[test]
fn moss_alone() {
    let e = run(&Recipe::single(Rule::Moss));
    check(&e, 0.5, 4.0);
    assert!(
        e.method.corr[1] > 0.7 && e.method.corr[2] > 0.7,
        "{:?}",
        e.method.corr
    );
}

/// All five rules at once, more than any recipe: measured L 0.81, a* 0.78, b* 0.67, W1 3.0 (kNN
/// floor 0.88, 0.80, 0.71, 2.4; the paper's affine mean 0.70, 0.66, 0.54, 4.4) at 12K points.
#[test]
fn every_rule_together() {
    let e = run(&Recipe::new("all", &Rule::ALL));
    check(&e, 0.8, 4.0);
    assert!(
        e.method.corr[1] > 0.7 && e.method.corr[2] > 0.6,
        "{:?}",
        e.method.corr
    );
}

/// Pearson correlation.
fn pearson(a: &[f32], b: &[f32]) -> f64 {
    let n = a.len().min(b.len()) as f64;
    let ma = a.iter().map(|&x| x as f64).sum::<f64>() / n;
    let mb = b.iter().map(|&x| x as f64).sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (x as f64 - ma, y as f64 - mb);
        sab += x * y;
        saa += x * x;
        sbb += y * y;
    }
    sab / (saa * sbb).sqrt().max(1e-30)
}

/// How much of each rule of `mossy` the transfer's colours on the cat carry: the correlation of
/// their greenness with the moss rule's strength there, and of their darkness with the dirt
/// rule's.
fn moss_and_dirt(e: &Evaluation) -> (f64, f64) {
    use meshmatch::synthesis::weathering::recipes::rule_strength;
    let p = pair();
    let ft = &p.target_features;
    let moss: Vec<f32> = (0..ft.len())
        .map(|v| rule_strength(Rule::Moss, ft, v, p.up))
        .collect();
    let dirt: Vec<f32> = (0..ft.len())
        .map(|v| rule_strength(Rule::Dirt, ft, v, p.up))
        .collect();
    let green: Vec<f32> = e
        .colors
        .iter()
        .map(|c| c[1] - 0.5 * (c[0] + c[2]))
        .collect();
    let dark: Vec<f32> = e.colors.iter().map(|c| -(c[0] + c[1] + c[2])).collect();
    (pearson(&green, &moss), pearson(&dark, &dirt))
}

/// The component that carries a rule: of the components whose largest standardised weight is on
/// one of `features`, the one with the highest canonical correlation.
fn carrier(r: &meshmatch::synthesis::weathering::CcaReport, features: &[&str]) -> usize {
    (0..r.correlations.len())
        .filter(|&k| features.contains(&r.top_features(k, 1)[0].0.as_str()))
        .max_by(|&a, &b| r.correlations[a].total_cmp(&r.correlations[b]))
        .unwrap_or_else(|| panic!("no component weighs {features:?} most:\n{}", r.to_text()))
}

/// The run of `recipe` with component `k` switched off.
fn without(recipe: &Recipe, k: usize, d: usize) -> Evaluation {
    let params = Params {
        components: Some((0..d).filter(|&j| j != k).collect()),
        ..Params::default()
    };
    let e = evaluate(pair(), recipe, &params, &CancelToken::new()).unwrap();
    assert_eq!(e.report.enabled.iter().filter(|e| !**e).count(), 1);
    e
}

/// The weathering window's switch: on `mossy` (moss on exposed tops, dirt in occluded
/// crevices), the component that carries the moss (weighing the up-facing normal or occlusion
/// most) switched off drops the moss and keeps the dirt; the one that carries the dirt (weighing
/// the ambient occlusion most) switched off drops the dirt and keeps the moss. Measured at 12K
/// points: moss 0.90, dirt 0.85 with every component; moss component off: moss 0.12, dirt 0.92;
/// dirt component off: moss 0.74, dirt 0.09 (correlations on the cat with each rule's strength).
#[test]
fn switching_off_a_component_drops_the_rule_it_carries_and_keeps_the_other() {
    let recipe = Recipe::new("mossy", &[Rule::Moss, Rule::Dirt]);
    let all = run(&recipe);
    let (moss_all, dirt_all) = moss_and_dirt(&all);
    let r = &all.report;
    eprint!("{}", r.to_text());
    let d = r.correlations.len();
    let km = carrier(r, &["normal-y", "occlusion-y"]);
    let kd = carrier(r, &["ao"]);
    assert_ne!(km, kd, "one component carries both rules");
    let (moss_m, dirt_m) = moss_and_dirt(&without(&recipe, km, d));
    let (moss_d, dirt_d) = moss_and_dirt(&without(&recipe, kd, d));
    eprintln!(
        "every component: moss {moss_all:.2} dirt {dirt_all:.2}; component {km} (moss) off: \
         moss {moss_m:.2} dirt {dirt_m:.2}; component {kd} (dirt) off: moss {moss_d:.2} dirt {dirt_d:.2}"
    );
    assert!(
        moss_all > 0.5 && dirt_all > 0.5,
        "{moss_all:.2} {dirt_all:.2}"
    );
    assert!(moss_m < 0.5 * moss_all, "moss still carried: {moss_m:.2}");
    assert!(dirt_m > 0.8 * dirt_all, "dirt lost too: {dirt_m:.2}");
    assert!(dirt_d < 0.5 * dirt_all, "dirt still carried: {dirt_d:.2}");
    // the moss rule also asks for open tops (occlusion), which the dirt component weighs: it
    // keeps most of its level, not all (measured 0.68 -> 0.48)
    assert!(moss_d > 0.6 * moss_all, "moss lost too: {moss_d:.2}");
}
