//! zenoh with TLS, mTLS and access control (docs/security.md, "zenoh"), inside a private
//! network namespace (`../shared/tools/netns-run`): certificates made now by
//! `tools/zenoh_certs.sh` (the `openssl` command line), the router (`ist_monitor zenoh-router`)
//! and the node started with the shipped `config/zenoh/secure_router.json5` and
//! `config/zenoh/secure_session.json5` (their relative `certs/` paths: both run in the folder
//! that holds them), and the cell's members and intruders as independent zenoh sessions (Python
//! `eclipse-zenoh`, `tests/python/zenoh_secure_peer.py`) publishing the camera's topic: the
//! camera a near cloud, each intruder a far cloud of its own, 50 ms after the camera's, which the
//! node would report if it got through; once with the router on `tls/` (the shipped configs as
//! they are) and once on `quic/` (the same configs, the endpoints switched by
//! `ZENOH_CONFIG_OVERRIDE` as docs/security.md's recipe does). The controls run the same
//! intruders (over `tls/`) with the access control off, and with no TLS at all: there they get
//! through, so the checks can fail.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use common::ist_monitor;
use ist_monitor::cloud::pointcloud2::{encode, Layout};
use ist_monitor::msg::{self, Header, Time};
use ist_monitor::query::{Backend, Engine, LinkSelection, Mode, QueryOptions};

const CLOUD_TOPIC: &str = "/camera/depth/points";

/// How far ahead of `camera_link` each session's patch is: the camera's is the near one; each
/// intruder's is farther, a distance of its own (all within the demo's `max_distance`).
const PATCHES: [(&str, f32); 5] = [
    ("camera", 0.6),
    ("tcp_no_certificate", 0.9),
    ("tls_no_certificate", 1.0),
    ("other_ca", 1.1),
    ("hmi_not_allowed", 1.2),
];

/// The test's folder: `certs/` (the cell's CA; router, ist_monitor, camera, hmi), `other/` (a
/// CA of its own and a `camera` it signs), each session's cloud, and the library's distance
/// for each patch.
struct Cell {
    dir: tempfile::TempDir,
    expected: Vec<(&'static str, f64)>,
}

/// The certificates and clouds, or None (with a skip printed) without `openssl` or Python
/// `eclipse-zenoh` outside CI.
fn cell(test: &str) -> Option<(Cell, PathBuf)> {
    let python = common::venv_python()?;
    let has = |c: &mut Command| c.output().is_ok_and(|o| o.status.success());
    if !has(Command::new(&python).args(["-c", "import zenoh"])) {
        assert!(std::env::var_os("CI").is_none(), "{test}: no eclipse-zenoh");
        common::skip("the venv has no eclipse-zenoh (bash .ci/run installs it)");
        return None;
    }
    if !has(Command::new("openssl").arg("version")) {
        assert!(std::env::var_os("CI").is_none(), "{test}: no openssl");
        common::skip("no `openssl` command (apt-get install openssl)");
        return None;
    }
    let dir = tempfile::tempdir().unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/zenoh_certs.sh");
    for (folder, names) in [
        ("certs", &["router", "ist_monitor", "camera", "hmi"][..]),
        ("other", &["camera"][..]),
    ] {
        let out = Command::new(&script)
            .arg(dir.path().join(folder))
            .args(names)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "zenoh_certs.sh: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    // The library's answer for each patch, as the node at rest measures it.
    let (model, trees) = common::demo_trees();
    let k = &model.kinematics;
    let poses = k.link_poses(&vec![0.0; k.variables().len()]);
    let camera_link = poses[k.link_index("camera_link").unwrap()];
    let mut engine = Engine::new(&model, &trees, &LinkSelection::default()).unwrap();
    let options = QueryOptions {
        mode: Mode::Certified,
        backend: Backend::Cpu,
        ..QueryOptions::default()
    };
    let mut expected = Vec::new();
    for (name, ahead) in PATCHES {
        let patch: Vec<[f32; 3]> = (0..20)
            .flat_map(|i| {
                (0..20).map(move |j| [ahead, -0.2 + 0.02 * i as f32, -0.2 + 0.02 * j as f32])
            })
            .collect();
        let header = Header {
            stamp: Time::from_nanos(1),
            frame_id: "camera_link".into(),
        };
        let cloud = encode(header, &patch, &Layout::unorganized(400)).unwrap();
        std::fs::write(
            dir.path().join(format!("{name}.cdr")),
            msg::encode(&cloud).unwrap(),
        )
        .unwrap();
        let r = engine
            .query(&patch, &camera_link, &poses, &options)
            .unwrap();
        expected.push((name, r.nearest.unwrap().lower_m.unwrap()));
    }
    // Each far cloud is told apart from the others and from the near one.
    for (i, a) in expected.iter().enumerate() {
        for b in &expected[i + 1..] {
            assert!((a.1 - b.1).abs() > 0.01, "{expected:?}");
        }
    }
    Some((Cell { dir, expected }, python))
}

impl Cell {
    fn path(&self, file: &str) -> String {
        self.dir.path().join(file).display().to_string()
    }

    fn expected(&self, name: &str) -> f64 {
        self.expected.iter().find(|e| e.0 == name).unwrap().1
    }

    /// `ist_monitor ARGS` run in the cell's folder with `env`, its log kept.
    fn spawn(&self, args: &[String], env: &[(&str, String)]) -> Child {
        let mut c = ist_monitor();
        c.current_dir(self.dir.path())
            .env("IST_MONITOR_DEMO_DIR", env!("CARGO_MANIFEST_DIR"))
            .env("RMW_IMPLEMENTATION", "rmw_zenoh_cpp")
            .env_remove("ZENOH_CONFIG_OVERRIDE")
            .env_remove("ZENOH_SESSION_CONFIG_URI")
            .env_remove("ZENOH_ROUTER_CONFIG_URI")
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        for (k, v) in env {
            c.env(k, v);
        }
        c.spawn().unwrap()
    }

    /// Runs the router (with `router_env`) and the node (with `node_env`), then the sessions
    /// of `plan` (name, zenoh config); returns the sessions' report and the node's log.
    fn run(
        &self,
        python: &Path,
        router_env: &[(&str, String)],
        node_env: &[(&str, String)],
        plan: &[(&str, serde_json::Value)],
    ) -> (serde_json::Value, String) {
        self.run_with(python, router_env, node_env, &[], plan)
    }

    /// As [`Cell::run`], the node started with `node_args` more.
    fn run_with(
        &self,
        python: &Path,
        router_env: &[(&str, String)],
        node_env: &[(&str, String)],
        node_args: &[&str],
        plan: &[(&str, serde_json::Value)],
    ) -> (serde_json::Value, String) {
        let router = self.spawn(&["zenoh-router".into()], router_env);
        std::thread::sleep(Duration::from_millis(700));
        let mut args = common::at_rest_args();
        args.extend(["-p".into(), "camera.source_timeout:=2.0".into()]);
        args.extend(node_args.iter().map(|a| a.to_string()));
        let node = self.spawn(&args, node_env);
        let sessions: Vec<serde_json::Value> = plan
            .iter()
            .map(|(name, config)| {
                serde_json::json!({"name": name, "config": config,
                                   "cloud": self.path(&format!("{name}.cdr"))})
            })
            .collect();
        let plan_file = self.dir.path().join("plan.json");
        std::fs::write(
            &plan_file,
            serde_json::json!({"topic": CLOUD_TOPIC, "seconds": 3.0, "wait": 60.0,
                               "sessions": sessions})
            .to_string(),
        )
        .unwrap();
        let script =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/zenoh_secure_peer.py");
        let peers = Command::new(python)
            .current_dir(self.dir.path())
            .arg(script)
            .arg(&plan_file)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let _reap = common::Reap(vec![router.id(), node.id(), peers.id()]);
        let out = peers.wait_with_output().unwrap();
        let log = stop(node);
        let router_log = stop(router);
        assert!(
            out.status.success(),
            "zenoh_secure_peer.py: {}\nnode: {log}\nrouter: {router_log}",
            String::from_utf8_lossy(&out.stderr)
        );
        (serde_json::from_slice(&out.stdout).unwrap(), log)
    }
}

/// Stops `child` with SIGTERM; its log.
fn stop(child: Child) -> String {
    let _ = Command::new("kill").arg(child.id().to_string()).status();
    let out = child.wait_with_output().unwrap();
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A zenoh client config of these keys (JSON5 values), as `insert_json5` takes them.
fn client(endpoint: &str, tls: &[(&str, &str)]) -> serde_json::Value {
    let mut c = serde_json::json!({
        "mode": "\"client\"",
        "connect/endpoints": format!("[\"{endpoint}\"]"),
        "scouting/multicast/enabled": "false",
    });
    for (k, v) in tls {
        c[format!("transport/link/tls/{k}")] = format!("\"{v}\"").into();
    }
    c
}

/// A member's TLS settings over `link` (`tls` or `quic`, which takes the same settings): the CA
/// it trusts, its certificate and key (`DIR/NAME.pem|key`).
fn member(link: &str, ca: &str, dir: &str, name: &str) -> serde_json::Value {
    let mut c = client(
        &format!("{link}/localhost:7447"),
        &[
            ("root_ca_certificate", ca),
            ("connect_certificate", &format!("{dir}/{name}.pem")),
            ("connect_private_key", &format!("{dir}/{name}.key")),
        ],
    );
    c["transport/link/tls/enable_mtls"] = "true".into();
    c
}

/// The camera and the four intruders, over the router's `link` (`tls` or `quic`): no
/// certificate over tcp, no certificate over `link` (`tls_no_certificate` whichever it is), a
/// certificate from another CA, and the HMI's (the cell's CA) which the rules do not let write.
fn plan(link: &str) -> Vec<(&'static str, serde_json::Value)> {
    vec![
        ("camera", member(link, "certs/ca.pem", "certs", "camera")),
        ("tcp_no_certificate", client("tcp/localhost:7447", &[])),
        (
            "tls_no_certificate",
            client(
                &format!("{link}/localhost:7447"),
                &[("root_ca_certificate", "certs/ca.pem")],
            ),
        ),
        // It trusts the router's CA; its own certificate is signed by another.
        ("other_ca", member(link, "certs/ca.pem", "other", "camera")),
        (
            "hmi_not_allowed",
            member(link, "certs/ca.pem", "certs", "hmi"),
        ),
    ]
}

/// The distances `session` received.
fn distances(report: &serde_json::Value, session: &str) -> Vec<f64> {
    (report[session]["distances"].as_array())
        .unwrap_or_else(|| panic!("{session}: {report}"))
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect()
}

/// Whether the distance of `name`'s patch is among `got`.
fn reported(cell: &Cell, got: &[f64], name: &str) -> bool {
    got.iter().any(|d| (d - cell.expected(name)).abs() < 1e-6)
}

/// The secured cell holds: (a) the camera, with its certificate, publishes its cloud and reads
/// `~/min_distance`, equal to the library's; (b) a session without a certificate (over tcp, or
/// over TLS without one) does not open; (c) nor does one whose certificate another CA signed;
/// (d) the HMI, with the cell's certificate, is connected (it reads the distances) but the
/// router drops the cloud it writes on the camera's topic: the node never reports it.
#[test]
fn zenoh_mtls_and_acl_keep_intruders_out() {
    secured_cell_holds("zenoh_mtls_and_acl_keep_intruders_out", "tls");
}

/// The same over QUIC, the link docs/security.md recommends for full-rate clouds: the shipped
/// configs with the one-line `ZENOH_CONFIG_OVERRIDE` of its recipe, for the router
/// (`listen/endpoints`) and the node (`connect/endpoints`); the members connect over `quic/`.
#[test]
fn zenoh_mtls_and_acl_keep_intruders_out_over_quic() {
    secured_cell_holds("zenoh_mtls_and_acl_keep_intruders_out_over_quic", "quic");
}

/// The checks (a) to (d) above, the router listening and the members connecting over `link`.
fn secured_cell_holds(test: &str, link: &str) {
    if !common::in_private_network(test) {
        return;
    }
    let Some((cell, python)) = cell(test) else {
        return;
    };
    let root = env!("CARGO_MANIFEST_DIR");
    let endpoints = format!("[\"{link}/localhost:7447\"]");
    let mut router_env = vec![(
        "ZENOH_ROUTER_CONFIG_URI",
        format!("{root}/config/zenoh/secure_router.json5"),
    )];
    let mut node_env = vec![(
        "ZENOH_SESSION_CONFIG_URI",
        format!("{root}/config/zenoh/secure_session.json5"),
    )];
    if link != "tls" {
        router_env.push((
            "ZENOH_CONFIG_OVERRIDE",
            format!("listen/endpoints={endpoints}"),
        ));
        node_env.push((
            "ZENOH_CONFIG_OVERRIDE",
            format!("connect/endpoints={endpoints}"),
        ));
    }
    let (report, log) = cell.run(&python, &router_env, &node_env, &plan(link));
    assert!(
        log.contains("secure_session.json5") && log.contains("1 router(s)"),
        "the node's start line names its config and its router: {log}"
    );
    // (a) The camera's distances, every one the library's for its cloud.
    let near = cell.expected("camera");
    for session in ["camera", "hmi_not_allowed"] {
        let got = distances(&report, session);
        assert!(
            got.len() >= 10,
            "{session}: {} distances: {report}",
            got.len()
        );
        for d in &got {
            assert!(
                (d - near).abs() < 1e-6,
                "{session} read {d}; the camera's cloud is at {near}: {report}"
            );
        }
    }
    // (b), (c) No link without a certificate of the cell's CA.
    for session in ["tcp_no_certificate", "tls_no_certificate", "other_ca"] {
        assert_eq!(
            report[session]["opened"], false,
            "{session} opened a session: {report}"
        );
    }
    // (d) The HMI is in (above: it read every distance) and published all along, but its cloud
    // never reached the node.
    assert_eq!(report["hmi_not_allowed"]["opened"], true, "{report}");
    assert!(
        !reported(&cell, &distances(&report, "camera"), "hmi_not_allowed"),
        "{report}"
    );
}

/// The controls of the test above, the same sessions: with the access control off (the same
/// router, TLS and mTLS kept), the HMI's cloud reaches the node while the sessions without the
/// cell's certificate still do not open; with rmw_zenoh's defaults (no TLS), the session without
/// a certificate opens and its cloud reaches the node.
#[test]
fn zenoh_without_acl_or_tls_the_intruders_get_through() {
    let test = "zenoh_without_acl_or_tls_the_intruders_get_through";
    if !common::in_private_network(test) {
        return;
    }
    let Some((cell, python)) = cell(test) else {
        return;
    };
    let root = env!("CARGO_MANIFEST_DIR");
    let router_env = [
        (
            "ZENOH_ROUTER_CONFIG_URI",
            format!("{root}/config/zenoh/secure_router.json5"),
        ),
        (
            "ZENOH_CONFIG_OVERRIDE",
            "access_control/enabled=false".into(),
        ),
    ];
    let node_env = [(
        "ZENOH_SESSION_CONFIG_URI",
        format!("{root}/config/zenoh/secure_session.json5"),
    )];
    // With the access control off, the HMI's publisher token reaches the node too: by
    // discovery two publishers of the camera's topic, the fault second_publisher, and no
    // distance at all, neither the camera's nor the HMI's, with the rule by messages off (a
    // window of 1 ns). With the access control on (the tests above), the router drops the
    // HMI's token and the camera's distances come.
    let by_discovery = ["-p", "second_publisher_window:=0.000000001"];
    let (report, log) = cell.run_with(&python, &router_env, &node_env, &by_discovery, &plan("tls"));
    assert_eq!(report["hmi_not_allowed"]["opened"], true, "{report}");
    assert!(distances(&report, "camera").is_empty(), "{report}\n{log}");
    // The one-voice rule off (not by discovery, and a window of 1 ns): an intruder's cloud
    // that gets through is then measured, and its distance is the proof.
    let no_voices = [
        "-p",
        "second_publisher_window:=0.000000001",
        "-p",
        "writers_from_discovery:=false",
    ];
    let (report, _) = cell.run_with(&python, &router_env, &node_env, &no_voices, &plan("tls"));
    let camera = distances(&report, "camera");
    assert!(reported(&cell, &camera, "camera"), "{report}");
    assert!(
        reported(&cell, &camera, "hmi_not_allowed"),
        "without the access control the HMI's cloud reaches the node: {report}"
    );
    for session in ["tcp_no_certificate", "tls_no_certificate", "other_ca"] {
        assert_eq!(report[session]["opened"], false, "{session}: {report}");
    }
    // No TLS: rmw_zenoh's default router and session.
    let plain = [
        ("camera", client("tcp/localhost:7447", &[])),
        ("tcp_no_certificate", client("tcp/localhost:7447", &[])),
    ];
    let (report, _) = cell.run_with(&python, &[], &[], &no_voices, &plain);
    let camera = distances(&report, "camera");
    assert!(reported(&cell, &camera, "camera"), "{report}");
    assert!(
        reported(&cell, &camera, "tcp_no_certificate"),
        "without TLS a session without a certificate reaches the node: {report}"
    );
}
