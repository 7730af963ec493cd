//! The SROS2 keystore tool (tools/sros2_keystore.py) checked with an independent reader of its
//! files: `openssl verify` and `openssl smime -verify` (every enclave's certificate chains to its
//! identity CA, governance and permissions verify against the permissions CA, a second keystore's
//! do not), and Cyclone DDS's DDS-Security plugins (participants secured by the cell policy's
//! enclaves exchange a cloud and its distance; one from another CA, and an unsecured one, get
//! nothing through).

mod common;

use common::cyclone::{build_peer, keystore_command, keystore_tool, peer_json};
use std::path::Path;
use std::process::{Command, Output};

const POLICY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/config/security/cell_policy.xml"
);
const ENCLAVES: [&str; 5] = [
    "/cell/camera",
    "/cell/controller",
    "/cell/ist_monitor",
    "/cell/operator",
    "/cell/robot_state_publisher",
];

fn openssl(args: &[&str]) -> Output {
    Command::new("openssl").args(args).output().unwrap()
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Whether `cert` chains to `ca` (openssl verify).
fn chains(cert: &Path, ca: &Path) -> bool {
    openssl(&["verify", "-CAfile", path(ca), path(cert)])
        .status
        .success()
}

/// The signed document's content where `signed` verifies against `ca`, else None.
fn verified(signed: &Path, ca: &Path) -> Option<String> {
    let out = openssl(&[
        "smime",
        "-verify",
        "-text",
        "-in",
        path(signed),
        "-CAfile",
        path(ca),
    ]);
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).replace("\r\n", "\n"))
}

#[test]
fn every_enclave_chains_to_the_keystores_cas_and_no_other() {
    let dir = tempfile::tempdir().unwrap();
    let ks = dir.path().join("keystore");
    let other = dir.path().join("other");
    keystore_tool(&["generate_artifacts", path(&ks), POLICY]);
    // A second keystore: its own CA under the same name (sros2CA), the wrong-CA case.
    keystore_tool(&["generate_artifacts", path(&other), POLICY, "/cell/camera"]);

    let listed = keystore_command(&["list_enclaves", path(&ks)])
        .output()
        .unwrap();
    assert_eq!(
        String::from_utf8_lossy(&listed.stdout)
            .lines()
            .collect::<Vec<_>>(),
        ENCLAVES
    );
    let public = ks.join("public");
    assert!(public.join("identity_ca.cert.pem").is_symlink());
    let governance = ks.join("enclaves/governance.xml");
    let signed = verified(
        &ks.join("enclaves/governance.p7s"),
        &public.join("ca.cert.pem"),
    );
    assert_eq!(
        signed.as_deref(),
        Some(std::fs::read_to_string(governance).unwrap().as_str())
    );

    for name in ENCLAVES {
        let e = ks.join("enclaves").join(&name[1..]);
        for f in [
            "cert.pem",
            "key.pem",
            "governance.p7s",
            "permissions.xml",
            "permissions.p7s",
        ] {
            assert!(e.join(f).is_file(), "{name}: {f} missing");
        }
        let identity_ca = e.join("identity_ca.cert.pem");
        let permissions_ca = e.join("permissions_ca.cert.pem");
        assert!(
            chains(&e.join("cert.pem"), &identity_ca),
            "{name}: cert.pem"
        );
        let subject = openssl(&[
            "x509",
            "-in",
            path(&e.join("cert.pem")),
            "-noout",
            "-subject",
        ]);
        assert_eq!(
            String::from_utf8_lossy(&subject.stdout).trim(),
            format!("subject=CN = {name}")
        );
        let permissions = verified(&e.join("permissions.p7s"), &permissions_ca)
            .unwrap_or_else(|| panic!("{name}: permissions.p7s does not verify"));
        assert_eq!(
            permissions,
            std::fs::read_to_string(e.join("permissions.xml")).unwrap()
        );
        assert!(permissions.contains(&format!("<subject_name>CN={name}</subject_name>")));
        assert!(verified(&e.join("governance.p7s"), &permissions_ca).is_some());
        // Nothing of this keystore verifies against the other's CA.
        let other_ca = other.join("public/ca.cert.pem");
        assert!(
            !chains(&e.join("cert.pem"), &other_ca),
            "{name} chains to another CA"
        );
        assert!(verified(&e.join("permissions.p7s"), &other_ca).is_none());
    }
    let wrong = other.join("enclaves/cell/camera");
    assert!(!chains(
        &wrong.join("cert.pem"),
        &public.join("identity_ca.cert.pem")
    ));
    assert!(verified(
        &wrong.join("permissions.p7s"),
        &public.join("permissions_ca.cert.pem")
    )
    .is_none());
}

#[test]
fn permissions_grant_what_the_policy_says_under_ros_names() {
    let dir = tempfile::tempdir().unwrap();
    let ks = dir.path().join("keystore");
    keystore_tool(&[
        "generate_artifacts",
        path(&ks),
        POLICY,
        "/cell/camera",
        "/cell/ist_monitor",
    ]);
    let read = |e: &str| {
        std::fs::read_to_string(ks.join("enclaves/cell").join(e).join("permissions.xml")).unwrap()
    };
    let section = |xml: &str, tag: &str| {
        // The first allow_rule's <publish> or <subscribe> topics.
        let start = xml.find(&format!("<{tag}>")).unwrap_or(0);
        let end = xml.find(&format!("</{tag}>")).unwrap_or(0);
        xml[start..end].to_owned()
    };
    let camera = read("camera");
    assert!(section(&camera, "publish").contains("<topic>rt/camera/depth/points</topic>"));
    assert!(
        !camera.contains("rt/ist_monitor/min_distance"),
        "the camera reads no outputs"
    );
    assert!(camera.contains("<topic>rr/camera/get_parametersReply</topic>"));
    let monitor = read("ist_monitor");
    let published = section(&monitor, "publish");
    let subscribed = section(&monitor, "subscribe");
    assert!(published.contains("<topic>rt/ist_monitor/min_distance</topic>"));
    assert!(published.contains("<topic>rt/ist_monitor/safety_stop</topic>"));
    assert!(
        !published.contains("rt/camera/depth/points"),
        "the node must not write its source"
    );
    assert!(subscribed.contains("<topic>rt/camera/depth/points</topic>"));
    assert!(subscribed.contains("<topic>rq/ist_monitor/set_parametersRequest</topic>"));
    assert!(monitor.contains("<topic>ros_discovery_info</topic>"));
    assert!(monitor.ends_with("<default>DENY</default>\n    </grant>\n  </permissions>\n</dds>\n"));
}

#[test]
fn a_separate_permissions_ca_and_governance_kinds() {
    let dir = tempfile::tempdir().unwrap();
    let ks = dir.path().join("ks");
    let ksp = path(&ks);
    keystore_tool(&[
        "create_keystore",
        ksp,
        "--separate-permissions-ca",
        "--protection",
        "NONE",
    ]);
    keystore_tool(&["create_enclave", ksp, "/robot/arm"]);
    let e = ks.join("enclaves/robot/arm");
    let (identity, permissions) = (
        e.join("identity_ca.cert.pem"),
        e.join("permissions_ca.cert.pem"),
    );
    assert!(chains(&e.join("cert.pem"), &identity));
    assert!(
        !chains(&e.join("cert.pem"), &permissions),
        "two CAs, two roles"
    );
    assert!(verified(&e.join("permissions.p7s"), &permissions).is_some());
    assert!(verified(&e.join("permissions.p7s"), &identity).is_none());
    let governance = verified(&e.join("governance.p7s"), &permissions).unwrap();
    assert_eq!(governance.matches(">NONE<").count(), 5, "{governance}");
    // sros2's wildcard permissions until a policy is applied.
    let wildcard = std::fs::read_to_string(e.join("permissions.xml")).unwrap();
    assert!(
        wildcard.contains("<topic>rt/*</topic>") && wildcard.contains("<topic>rq/*Request</topic>")
    );
    // A re-signed governance reaches every enclave (their governance.p7s is a link).
    keystore_tool(&["create_governance", ksp, "--data-protection", "SIGN"]);
    let governance = verified(&e.join("governance.p7s"), &permissions).unwrap();
    assert!(governance.contains("<data_protection_kind>SIGN</data_protection_kind>"));
    assert!(governance.contains("<rtps_protection_kind>SIGN</rtps_protection_kind>"));
    assert!(governance.contains("<metadata_protection_kind>ENCRYPT</metadata_protection_kind>"));
}

#[test]
fn bad_input_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let ks = dir.path().join("ks");
    let ksp = path(&ks);
    let err = |args: &[&str]| {
        let out = keystore_command(args).output().unwrap();
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    assert!(err(&["create_enclave", ksp, "/a"]).contains("is not a keystore"));
    keystore_tool(&["create_keystore", ksp]);
    assert!(err(&["create_keystore", ksp]).contains("already holds a keystore"));
    assert!(err(&["create_enclave", ksp, "/1bad//name"]).contains("'/1bad//name' is not a valid"));
    let policy = dir.path().join("p.xml");
    std::fs::write(&policy, r#"<policy version="0.2.0"><enclaves><enclave path="/a"><profiles><profile ns="/" node="n"><topics publish="MAYBE"><topic>x</topic></topics></profile></profiles></enclave></enclaves></policy>"#).unwrap();
    keystore_tool(&["create_enclave", ksp, "/a"]);
    let e = err(&["create_permission", ksp, "/a", path(&policy)]);
    assert!(
        e.contains(path(&policy)) && e.contains("publish=\"MAYBE\""),
        "{e}"
    );
    let e = err(&["create_permission", ksp, "/b", POLICY]);
    assert!(
        e.contains("no enclave '/b'") && e.contains("/cell/camera"),
        "{e}"
    );
}

/// Runs the peers of one phase at once, each `(enclave or None, extra args)`.
fn run_peers(exe: &Path, ks: &Path, peers: &[(Option<&Path>, &[&str])]) -> Vec<serde_json::Value> {
    let children: Vec<_> = peers
        .iter()
        .map(|(enclave, args)| {
            let mut c = Command::new(exe);
            if let Some(e) = enclave {
                c.arg("--enclave").arg(ks.join(e));
            }
            c.args(*args)
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    let _reap = common::Reap(children.iter().map(|c| c.id()).collect());
    children
        .into_iter()
        .map(|c| peer_json(&c.wait_with_output().unwrap()))
        .collect()
}

#[test]
fn cyclone_participants_talk_only_within_the_keystore() {
    if !common::in_private_network("cyclone_participants_talk_only_within_the_keystore") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let Some(exe) = build_peer(dir.path()) else {
        return;
    };
    let (ks, other) = (dir.path().join("ks"), dir.path().join("other"));
    keystore_tool(&[
        "generate_artifacts",
        path(&ks),
        POLICY,
        "/cell/camera",
        "/cell/ist_monitor",
        "/cell/operator",
    ]);
    keystore_tool(&["generate_artifacts", path(&other), POLICY, "/cell/camera"]);
    let e = |name: &str| ks.join("enclaves/cell").join(name);
    let wrong = other.join("enclaves/cell/camera");

    // The cell: the camera publishes, a stand-in for the node (its enclave) answers each cloud
    // with its nearest point's distance, the operator reads it.
    let out = run_peers(
        &exe,
        &ks,
        &[
            (Some(&e("ist_monitor")), &["--monitor", "--timeout", "8"]),
            (Some(&e("camera")), &["--no-float", "--timeout", "8"]),
            (
                Some(&e("operator")),
                &["--no-cloud", "--timeout", "8", "--count", "3"],
            ),
        ],
    );
    let (monitor, operator) = (&out[0], &out[2]);
    assert!(monitor["clouds_received"].as_u64().unwrap() > 0, "{out:?}");
    let values = operator["values"].as_array().unwrap();
    assert!(!values.is_empty(), "{out:?}");
    // The plane's nearest point, (0.6, 0, 0) in float32.
    assert!(
        values
            .iter()
            .all(|v| (v.as_f64().unwrap() - 0.6).abs() < 1e-6),
        "{out:?}"
    );

    // Another CA's camera and an unsecured one: no match, no cloud in.
    let out = run_peers(
        &exe,
        &ks,
        &[
            (Some(&e("ist_monitor")), &["--monitor", "--timeout", "6"]),
            (Some(&wrong), &["--no-float", "--timeout", "6"]),
            (None, &["--no-float", "--timeout", "6"]),
        ],
    );
    assert_eq!(out[0]["clouds_received"], 0, "{out:?}");
    assert_eq!(out[0]["cloud_matched"], 0, "{out:?}");
    assert!(
        out[1]["clouds_sent"].as_u64().unwrap() > 0 && out[1]["cloud_matched"] == 0,
        "{out:?}"
    );
    assert_eq!(out[2]["cloud_matched"], 0, "{out:?}");
}
