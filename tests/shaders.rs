//! CPU-only checks of the WGSL shaders: the shader as the host composes it, both ways it keeps
//! the minima (`Minima`) and both ways it reduces in a workgroup (`Reduce`), parses and validates with naga with the capabilities the host asks for
//! (after the constants it generates), every file in `shaders/` is part of it, every struct the
//! host mirrors has the host's size and the host's members at the host's offsets, and no file
//! declares a generated constant itself.

use ist_monitor::query::layout::{
    cell_source, shader_source, unproject_source, wgsl_constants, Minima, Mirror, Reduce,
    CELL_MIRRORS, CELL_WGSL, MINIMA_U32_WGSL, MINIMA_U64_WGSL, MIRRORS, REDUCE_SHARED_WGSL,
    REDUCE_SUBGROUPS_WGSL, TRAVERSE_WGSL, UNPROJECT_MIRRORS, UNPROJECT_WGSL,
};
use naga::valid::{Capabilities, ShaderStages, SubgroupOperationSet};

/// Each way of keeping the minima and of reducing in a workgroup, with the capabilities the
/// host requests for it.
const VARIANTS: [(Minima, Reduce, Capabilities); 4] = {
    const INT64: Capabilities =
        Capabilities::SHADER_INT64.union(Capabilities::SHADER_INT64_ATOMIC_MIN_MAX);
    [
        (
            Minima::Packed64,
            Reduce::Subgroups,
            INT64.union(Capabilities::SUBGROUP),
        ),
        (Minima::Packed64, Reduce::Shared, INT64),
        (Minima::Split32, Reduce::Subgroups, Capabilities::SUBGROUP),
        (Minima::Split32, Reduce::Shared, Capabilities::empty()),
    ]
};

/// `source` parsed and validated with `capabilities` (subgroup operations in compute shaders
/// where they include `SUBGROUP`, as wgpu's `SUBGROUP` feature gives them).
fn module(source: &str, name: &str, capabilities: Capabilities) -> naga::Module {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
    let mut validator =
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), capabilities);
    if capabilities.contains(Capabilities::SUBGROUP) {
        validator
            .subgroup_stages(ShaderStages::COMPUTE)
            .subgroup_operations(SubgroupOperationSet::all());
    }
    validator
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
    module
}

#[test]
fn the_composed_shader_validates_both_ways_and_uses_every_file() {
    for (minima, reduce, capabilities) in VARIANTS {
        let source = shader_source(minima, reduce);
        let m = module(&source, &format!("{minima:?} {reduce:?}"), capabilities);
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
    // The 64-bit and the subgroup variants need their capabilities: they are never compiled
    // without them.
    for (minima, reduce) in [
        (Minima::Packed64, Reduce::Shared),
        (Minima::Split32, Reduce::Subgroups),
    ] {
        let source = shader_source(minima, reduce);
        let parsed = naga::front::wgsl::parse_str(&source).unwrap();
        assert!(
            naga::valid::Validator::new(naga::valid::ValidationFlags::all(), Capabilities::empty())
                .validate(&parsed)
                .is_err(),
            "{minima:?} {reduce:?}"
        );
    }
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    // The depth images' unprojection is a module of its own, with its one pass.
    let m = module(&unproject_source(), "unproject", Capabilities::empty());
    let entries: Vec<&str> = m.entry_points.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(entries, ["unproject"]);
    // The unseen space's cells likewise.
    let m = module(&cell_source(), "cell", Capabilities::empty());
    let entries: Vec<&str> = m.entry_points.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(entries, ["judge_cells"]);
    let used = [
        TRAVERSE_WGSL,
        MINIMA_U64_WGSL,
        MINIMA_U32_WGSL,
        REDUCE_SUBGROUPS_WGSL,
        REDUCE_SHARED_WGSL,
        UNPROJECT_WGSL,
        CELL_WGSL,
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
        .map(|(minima, reduce, capabilities)| {
            let name = format!("{minima:?} {reduce:?}");
            let m = module(&shader_source(*minima, *reduce), &name, *capabilities);
            (m, MIRRORS)
        })
        .collect();
    modules.push((
        module(&unproject_source(), "unproject", Capabilities::empty()),
        UNPROJECT_MIRRORS,
    ));
    modules.push((
        module(&cell_source(), "cell", Capabilities::empty()),
        CELL_MIRRORS,
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
            ("reduce_subgroups.wgsl", REDUCE_SUBGROUPS_WGSL),
            ("reduce_shared.wgsl", REDUCE_SHARED_WGSL),
            ("unproject.wgsl", UNPROJECT_WGSL),
            ("cell.wgsl", CELL_WGSL),
        ] {
            assert!(
                !text.contains(&format!("const {name}:")),
                "shaders/{file} declares {name}, which the host generates"
            );
        }
    }
}
