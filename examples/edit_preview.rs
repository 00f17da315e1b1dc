//! What a correspondence edit shows first: the preview from the map the previous solve left,
//! the first preview a solve with the new map gives, and the finished transfer, as PLYs of the
//! target's working mesh (render them with `meshmatch render`):
//! `cargo run --release --example edit_preview -- DEMO_DIR OUT_DIR` with `DEMO_DIR` written by
//! `meshmatch demo --out DEMO_DIR` (zebra -> giraffe; the edit adds the last correspondence).

use meshmatch::correspondence::{Correspondence, CorrespondenceFile};
use meshmatch::mesh::io::{PlyOptions, load, save_ply};
use meshmatch::meshmatch::{PreparedMesh, TransferParams, prepare_pair, solve};
use meshmatch::work::{CancelToken, Event};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

fn main() -> meshmatch::error::Result<()> {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let (demo, out) = match args.as_slice() {
        [d, o] => (d.clone(), o.clone()),
        _ => {
            eprintln!("usage: edit_preview DEMO_DIR OUT_DIR");
            std::process::exit(2);
        }
    };
    std::fs::create_dir_all(&out).expect("create the output folder");
    let zebra = load(&demo.join("zebra.glb"))?;
    let giraffe = load(&demo.join("giraffe.glb"))?;
    let corr = CorrespondenceFile::load(&demo.join("zebra_to_giraffe.json"))?.correspondences;
    let params = TransferParams::default();
    let cancel = CancelToken::new();
    let prepared = || prepare_pair(&zebra, &params, &giraffe, &params, &|_| {}, &cancel);
    // the first partial result and when it came
    let run = |ps: &PreparedMesh, pt: &PreparedMesh, corr: &[Correspondence]| {
        let t0 = Instant::now();
        let first = Mutex::new(None::<(f64, Vec<[f32; 3]>)>);
        let sink = |e: Event| {
            if let Event::Partial { signal, .. } = e {
                first
                    .lock()
                    .unwrap()
                    .get_or_insert_with(|| (t0.elapsed().as_secs_f64(), signal.to_vec()));
            }
        };
        let r = solve(ps, pt, corr, &params, &sink, &cancel)?;
        let done = t0.elapsed().as_secs_f64();
        Ok::<_, meshmatch::error::Error>((r, first.into_inner().unwrap().unwrap(), done))
    };
    let save = |pt: &PreparedMesh, sig: &[[f32; 3]], name: &str| {
        let mut m = pt.working_mesh().clone();
        m.colors = Some(sig.to_vec());
        (m.uvs, m.texture) = (None, None);
        save_ply(&m, &out.join(name), &PlyOptions::default())
    };
    let n = corr.len();
    let (ps, pt) = prepared()?;
    run(&ps, &pt, &corr[..n - 1])?;
    let (edited, (t_prev, prev), done) = run(&ps, &pt, &corr)?;
    println!("after the edit: first preview {t_prev:.3} s (previous map), finished {done:.2} s");
    let (fs, ft) = prepared()?;
    let (fresh, (t_new, new), done) = run(&fs, &ft, &corr)?;
    println!("fresh solve: first preview {t_new:.3} s (new map), finished {done:.2} s");
    assert_eq!(edited.working_signal, fresh.working_signal);
    save(&pt, &prev, "preview_previous_map.ply")?;
    save(&ft, &new, "preview_new_map.ply")?;
    save(&pt, &edited.working_signal, "finished.ply")?;
    Ok(())
}
