//! CPU-only checks of the WGSL shaders: every file in `shaders/` parses and validates with naga
//! (after the constants the host generates), every struct the host mirrors has the host's size
//! and the host's members at the host's offsets, and the shader declares none of the generated
//! constants itself.

use ist_monitor::query::layout::{shader_source, wgsl_constants, MIRRORS, TRAVERSE_WGSL};

fn module(source: &str, name: &str) -> naga::Module {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name}: {e:?}"));
    module
}

#[test]
fn every_shader_parses_and_validates() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "wgsl") {
            let text = std::fs::read_to_string(&path).unwrap();
            module(
                &format!("{}\n{text}", wgsl_constants()),
                &path.display().to_string(),
            );
            n += 1;
        }
    }
    assert!(n >= 1);
    module(&shader_source(), "shader_source()");
}

#[test]
fn mirrored_structs_have_the_host_members_at_the_host_offsets() {
    let module = module(&shader_source(), "traverse.wgsl");
    for mirror in MIRRORS {
        let ty = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(mirror.wgsl))
            .unwrap_or_else(|| panic!("struct {} not in traverse.wgsl", mirror.wgsl));
        let (members, span) = match &ty.1.inner {
            naga::TypeInner::Struct { members, span } => (members, *span as usize),
            other => panic!("{} is not a struct: {other:?}", mirror.wgsl),
        };
        assert_eq!(
            span, mirror.size,
            "{}: WGSL {span} bytes, host {}",
            mirror.wgsl, mirror.size
        );
        let wgsl: Vec<(String, usize)> = members
            .iter()
            .map(|m| (m.name.clone().unwrap_or_default(), m.offset as usize))
            .collect();
        let host: Vec<(String, usize)> = mirror
            .members
            .iter()
            .map(|&(n, o)| (n.to_owned(), o))
            .collect();
        assert_eq!(wgsl, host, "{}: members (name, offset)", mirror.wgsl);
    }
}

#[test]
fn the_shader_file_declares_none_of_the_generated_constants() {
    for line in wgsl_constants().lines().filter(|l| l.starts_with("const ")) {
        let name = line["const ".len()..].split(':').next().unwrap();
        assert!(
            !TRAVERSE_WGSL.contains(&format!("const {name}:")),
            "shaders/traverse.wgsl declares {name}, which the host generates"
        );
    }
}
