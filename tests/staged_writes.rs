//! All-or-nothing outputs: inside a `StagedWrites` group (the CLI opens one around every
//! subcommand) no existing file is replaced until the group commits, and a group dropped after a
//! failure leaves every file as it was and no temporary behind. (Its own test binary: the group
//! is process-wide.)

mod scratch;
use scratch::Scratch;

use meshmatch::mesh::io::{StagedWrites, write_atomic};

#[test]
fn a_failed_command_replaces_nothing_and_a_committed_one_replaces_everything() {
    let d = Scratch::new("staged");
    let (a, b) = (d.join("a.ply"), d.join("b.csv"));
    std::fs::write(&a, "old a").unwrap();
    std::fs::write(&b, "old b").unwrap();
    let listing = || {
        let mut v: Vec<String> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    // the first output is written, the second fails: the group is dropped
    {
        let _g = StagedWrites::begin();
        write_atomic(&a, b"new a").unwrap();
        assert_eq!(
            std::fs::read_to_string(&a).unwrap(),
            "old a",
            "replaced too early"
        );
        let bad = d.join("missing-folder").join("c.png");
        assert!(write_atomic(&bad, b"png").is_err());
    }
    assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
    assert_eq!(std::fs::read_to_string(&b).unwrap(), "old b");
    assert_eq!(listing(), ["a.ply", "b.csv"], "temporaries left behind");
    // a successful command: both replaced at the commit
    let g = StagedWrites::begin();
    write_atomic(&a, b"new a").unwrap();
    write_atomic(&b, b"new b").unwrap();
    write_atomic(&d.join("c.txt"), b"new c").unwrap();
    assert!(!d.join("c.txt").exists());
    g.commit().unwrap();
    assert_eq!(std::fs::read_to_string(&a).unwrap(), "new a");
    assert_eq!(std::fs::read_to_string(&b).unwrap(), "new b");
    assert_eq!(listing(), ["a.ply", "b.csv", "c.txt"]);
    // outside a group, writes land at once
    write_atomic(&a, b"direct").unwrap();
    assert_eq!(std::fs::read_to_string(&a).unwrap(), "direct");
    // a .gltf and the buffer and texture beside it: a failed command leaves none of the three
    let mut spot =
        meshmatch::mesh::io::load(&meshmatch::testdata::data_path("spot/spot.obj")).expect("spot");
    spot.colors = None;
    let gone = d.join("staged.gltf");
    {
        let _group = StagedWrites::begin();
        meshmatch::mesh::io::save(&spot, &gone).unwrap();
    }
    for name in ["staged.gltf", "staged.bin", "staged_texture.png"] {
        assert!(!d.join(name).exists(), "{name} left behind");
    }
    assert_eq!(
        listing(),
        ["a.ply", "b.csv", "c.txt"],
        "temporaries left behind"
    );
    let _ = std::fs::remove_dir_all(&d);
}
