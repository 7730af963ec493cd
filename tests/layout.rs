//! The house's layout rules (../shared/STYLE.md, "When a room grows") hold on src/: no folder
//! face (`mod.rs`) over 150 lines, no file over 700, no function over 150, no child module
//! importing its parent's definitions, no import cycle between the files of one folder.
//! `tools/layout_check.py` measures them; this runs it, so that a change that breaks one fails.

mod common;

use std::process::Command;

const SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tools/layout_check.py");

/// The checker's exit status and report on the tree at `root`; None where python3 is missing
/// outside CI (the test then skips, saying so).
fn check(root: &std::path::Path) -> Option<(bool, String)> {
    match Command::new("python3")
        .arg(SCRIPT)
        .arg("--root")
        .arg(root)
        .output()
    {
        Ok(out) => Some((
            out.status.success(),
            String::from_utf8_lossy(&out.stdout).into_owned()
                + &String::from_utf8_lossy(&out.stderr),
        )),
        Err(e) if std::env::var_os("CI").is_none() => {
            common::skip(&format!(
                "python3 could not be started ({e}) and CI is not set"
            ));
            None
        }
        Err(e) => panic!("CI is set but python3 could not be started: {e}"),
    }
}

#[test]
fn the_layout_rules_hold_on_src() {
    let Some((ok, report)) = check(env!("CARGO_MANIFEST_DIR").as_ref()) else {
        return;
    };
    assert!(ok, "{SCRIPT} found breaches:\n{report}");
    assert!(report.contains("layout: 0 breaches"), "{report}");
}

/// The checker finds each kind of breach in a small tree made to have one of each.
#[test]
fn the_checker_finds_each_kind_of_breach() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let src = dir.path().join("src");
    std::fs::create_dir_all(src.join("area")).expect("src/area");
    let write = |path: &str, text: String| std::fs::write(src.join(path), text).expect(path);
    write("lib.rs", "pub mod area;\n".into());
    let long_fn = format!("fn long() {{\n{}}}\n", "    let _ = 1;\n".repeat(151));
    write(
        "area/mod.rs",
        format!(
            "mod a;\nmod b;\npub struct Face;\n{}",
            "// filler\n".repeat(150)
        ),
    );
    write(
        "area/a.rs",
        format!("use super::b::B;\npub struct A;\n{long_fn}"),
    );
    write(
        "area/b.rs",
        "use super::a::A;\nuse super::Face;\npub struct B;\n".into(),
    );
    write("area/big.rs", "// filler\n".repeat(701));
    write("area/mod.rs", {
        let face = std::fs::read_to_string(src.join("area/mod.rs")).expect("mod.rs");
        face.replacen("mod b;\n", "mod b;\nmod big;\n", 1)
    });
    let Some((ok, report)) = check(dir.path()) else {
        return;
    };
    assert!(!ok, "{report}");
    for breach in [
        "src/area/mod.rs: a folder face of",
        "src/area/big.rs: 701 lines",
        "fn long is 153 lines",
        "src/area/b.rs: imports `Face` defined in its parent",
        "import cycle in src/area/: src/area/a.rs, src/area/b.rs",
    ] {
        assert!(report.contains(breach), "missing '{breach}' in:\n{report}");
    }
}
