//! CPU-only checks of the WGSL shaders: the shader as the host composes it, both ways it keeps
//! the minima (`Minima`), parses and validates with naga with the capabilities the host asks for
//! (after the constants it generates), every file in `shaders/` is part of it, every struct the
//! host mirrors has the host's size and the host's members at the host's offsets, and no file
//! declares a generated constant itself.

use ist_monitor::query::layout::{
    shader_source, unproject_source, wgsl_constants, Minima, Mirror, MINIMA_U32_WGSL,
    MINIMA_U64_WGSL, MIRRORS, TRAVERSE_WGSL, UNPROJECT_MIRRORS, UNPROJECT_WGSL,
};
use naga::valid::Capabilities;

/// Each way of keeping the minima, with the capabilities the host requests for it.
const VARIANTS: [(Minima, Capabilities); 2] = [
    (
        Minima::Packed64,
        Capabilities::SHADER_INT64.union(Capabilities::SHADER_INT64_ATOMIC_MIN_MAX),
    ),
    (Minima::Split32, Capabilities::empty()),
];

fn module(source: &str, name: &str, capabilities: Capabilities) -> naga::Module {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), capabilities)
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
    module
}

#[test]
fn the_composed_shader_validates_both_ways_and_uses_every_file() {
    for (minima, capabilities) in VARIANTS {
        let source = shader_source(minima);
        let m = module(&source, &format!("{minima:?}"), capabilities);
        // The passes the host dispatches.
        let mut entries: Vec<&str> = m.entry_points.iter().map(|e| e.name.as_str()).collect();
        entries.sort_unstable();
        let mut expected = vec![
            "blocks",
            "cull",
            "measure",
            "plan",
            "seed",
            "seed_scan",
            "tally",
        ];
        if minima == Minima::Split32 {
            expected.extend(["argmin", "seed_pick"]);
            expected.sort_unstable();
        }
        assert_eq!(entries, expected, "{minima:?}");
    }
    // The 64-bit variant needs its capabilities: it is never compiled without them.
    let source = shader_source(Minima::Packed64);
    let parsed = naga::front::wgsl::parse_str(&source).unwrap();
    assert!(naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        Capabilities::empty()
    )
    .validate(&parsed)
    .is_err());
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    // The depth images' unprojection is a module of its own, with its one pass.
    let m = module(&unproject_source(), "unproject", Capabilities::empty());
    let entries: Vec<&str> = m.entry_points.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(entries, ["unproject"]);
    let used = [
        TRAVERSE_WGSL,
        MINIMA_U64_WGSL,
        MINIMA_U32_WGSL,
        UNPROJECT_WGSL,
    ];
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "wgsl") {
            let text = std::fs::read_to_string(&path).unwrap();
            assert!(
                used.contains(&text.as_str()),
                "{} is not part of the composed shader",
                path.display()
            );
            n += 1;
        }
    }
    assert_eq!(n, used.len());
}

#[test]
fn mirrored_structs_have_the_host_members_at_the_host_offsets() {
    let mut modules: Vec<(naga::Module, &[Mirror])> = VARIANTS
        .iter()
        .map(|(minima, capabilities)| {
            let m = module(
                &shader_source(*minima),
                &format!("{minima:?}"),
                *capabilities,
            );
            (m, MIRRORS)
        })
        .collect();
    modules.push((
        module(&unproject_source(), "unproject", Capabilities::empty()),
        UNPROJECT_MIRRORS,
    ));
    for (module, mirrors) in &modules {
        for mirror in *mirrors {
            let ty = module
                .types
                .iter()
                .find(|(_, t)| t.name.as_deref() == Some(mirror.wgsl))
                .unwrap_or_else(|| panic!("struct {} not in the shader", mirror.wgsl));
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
}

#[test]
fn no_shader_file_declares_a_generated_constant() {
    for line in wgsl_constants().lines().filter(|l| l.starts_with("const ")) {
        let name = line["const ".len()..].split(':').next().unwrap();
        for (file, text) in [
            ("traverse.wgsl", TRAVERSE_WGSL),
            ("minima_u64.wgsl", MINIMA_U64_WGSL),
            ("minima_u32.wgsl", MINIMA_U32_WGSL),
            ("unproject.wgsl", UNPROJECT_WGSL),
        ] {
            assert!(
                !text.contains(&format!("const {name}:")),
                "shaders/{file} declares {name}, which the host generates"
            );
        }
    }
}
