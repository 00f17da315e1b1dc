//! Full-resolution delivery against ground truth: Spot's surface re-tessellated (and bent and
//! moved), a UV atlas on the target, the true texture through the known correspondence; the
//! transfer's texture delivered at full resolution, from the working vertices, and the
//! point-to-surface pull-back, each scored texel by texel (mean CIE76 dE, SSIM of the
//! lightness, edge strength on the truth's strongest edges).
//!
//! `cargo run --release --example texel_truth -- [vertices] [texture size] [out dir]`
//! (defaults 64000, 1024, no images written). With an out dir, each task's truth and
//! deliveries are written as PNGs there. `TASKS=spot,bricks bent` runs only those tasks.

use meshmatch::ground_truth::{Deformation, TexelTask, TextureKind, detailed_texture};
use meshmatch::mesh::{Texture, io};
use meshmatch::meshmatch::TransferParams;
use meshmatch::testdata::data_path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let vertices: usize = args
        .first()
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(64_000);
    let size: u32 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(1024);
    let out = args.get(2).map(std::path::PathBuf::from);
    if let Some(o) = &out {
        std::fs::create_dir_all(o)?;
    }
    let spot = io::load(&data_path("spot/spot.obj"))?;
    let with = |kind: Option<TextureKind>| {
        let mut m = spot.clone();
        if let Some(k) = kind {
            m.texture = Some(std::sync::Arc::new(Texture {
                image: detailed_texture(k, 2048),
                path: None,
            }));
        }
        m
    };
    let tasks = [
        ("spot", None, Deformation::None),
        ("spot bent", None, Deformation::BentAndMoved),
        ("bricks", Some(TextureKind::Bricks), Deformation::None),
        (
            "bricks bent",
            Some(TextureKind::Bricks),
            Deformation::BentAndMoved,
        ),
        ("mixed", Some(TextureKind::Mixed), Deformation::None),
        (
            "mixed bent",
            Some(TextureKind::Mixed),
            Deformation::BentAndMoved,
        ),
        ("spot twisted", None, Deformation::TwistedAndMoved),
        (
            "bricks twisted",
            Some(TextureKind::Bricks),
            Deformation::TwistedAndMoved,
        ),
        ("spot posed", None, Deformation::PosedAndMoved),
        (
            "bricks posed",
            Some(TextureKind::Bricks),
            Deformation::PosedAndMoved,
        ),
    ];
    let params = TransferParams {
        vertices,
        ..TransferParams::default()
    };
    println!(
        "{vertices} working vertices, {size}^2 output texels; target: Spot re-tessellated at 12K vertices"
    );
    println!(
        "| task | method | texel dE | SSIM | edges | sharpness | deliver s |\n| --- | --- | ---: | ---: | ---: | ---: | ---: |"
    );
    let only = std::env::var("TASKS").ok();
    for (name, kind, deformation) in tasks {
        if only
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|t| t == name))
        {
            continue;
        }
        let task = TexelTask::new(with(kind), 12_000, deformation, size, 7)?;
        let c = task.compare(&params, size)?;
        eprintln!(
            "{name}: solve {:.1} s, placement median {:.2} / p90 {:.2} source edges, {:.0}% read exactly where the shapes coincide",
            c.solve_seconds,
            c.placement[0],
            c.placement[1],
            100.0 * c.coincident
        );
        for d in &c.deliveries {
            println!(
                "| {name} | {} | {:.2} | {:.3} | {:.2} | {:.2} | {:.2} |",
                d.method,
                d.scores.delta_e,
                d.scores.ssim,
                d.scores.edges,
                d.scores.sharpness,
                d.seconds
            );
        }
        if let Some(o) = &out {
            let stem = name.replace(' ', "_");
            c.truth.save(o.join(format!("{stem}_truth.png")))?;
            for d in &c.deliveries {
                let m = d.method.replace([' ', '-'], "_");
                d.image.save(o.join(format!("{stem}_{m}.png")))?;
            }
        }
    }
    Ok(())
}
