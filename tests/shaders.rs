//! CPU-only checks of the WGSL shaders: every file in `shaders/` parses and validates with naga,
//! and every struct the host mirrors has the host's size.

use ist_monitor::query::gpu::{MIRRORS, SHADER};

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
            module(
                &std::fs::read_to_string(&path).unwrap(),
                &path.display().to_string(),
            );
            n += 1;
        }
    }
    assert!(n >= 1);
}

#[test]
fn mirrored_structs_have_the_host_sizes() {
    let module = module(SHADER, "traverse.wgsl");
    for &(name, host) in MIRRORS {
        let ty = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("struct {name} not in traverse.wgsl"));
        let size = match &ty.1.inner {
            naga::TypeInner::Struct { span, .. } => *span as usize,
            other => panic!("{name} is not a struct: {other:?}"),
        };
        assert_eq!(size, host, "{name}: WGSL {size} bytes, host {host}");
    }
}
