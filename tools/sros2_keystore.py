#!/usr/bin/env python3
"""An SROS2 keystore without ROS: the files `ros2 security` (sros2, Jazzy) makes, made with the
`openssl` command line and the Python standard library, for rcl nodes, ist_monitor and any
DDS-Security 1.1 implementation (Fast DDS, Cyclone DDS, RustDDS).

  sros2_keystore.py create_keystore KS [--common-name CN] [--separate-permissions-ca]
                                       [--domain-id N] [governance options]
  sros2_keystore.py create_governance KS [governance options]     (rewrite and re-sign it)
  sros2_keystore.py create_enclave KS /enclave/path
  sros2_keystore.py create_permission KS /enclave/path POLICY.xml
  sros2_keystore.py generate_artifacts KS POLICY.xml [/enclave/path ...]
  sros2_keystore.py list_enclaves KS

Governance options (defaults: sros2's governance template): --protection KIND sets all five
kinds at once; --discovery-protection, --liveliness-protection, --rtps-protection,
--metadata-protection, --data-protection KIND (ENCRYPT, SIGN or NONE; sros2: ENCRYPT, ENCRYPT,
SIGN, ENCRYPT, ENCRYPT); --allow-unauthenticated-participants; --no-join-access-control.

The layout is sros2's (sros2/keystore/_keystore.py, _enclave.py, _permission.py):

  KS/public/ca.cert.pem           the CA (CN=sros2CA, EC prime256v1, CA:TRUE pathlen 1 critical)
  KS/public/identity_ca.cert.pem  -> ca.cert.pem     (one CA for both roles, as sros2 makes it)
  KS/public/permissions_ca.cert.pem -> ca.cert.pem
  KS/private/ca.key.pem, identity_ca.key.pem, permissions_ca.key.pem (links likewise)
  KS/enclaves/governance.xml, governance.p7s   (S/MIME, signed by the permissions CA)
  KS/enclaves/<path>/cert.pem key.pem          (CN=<path>, signed by the identity CA)
  KS/enclaves/<path>/identity_ca.cert.pem permissions_ca.cert.pem governance.p7s  (relative links)
  KS/enclaves/<path>/permissions.xml permissions.p7s

Certificates are valid from one day before their creation for 3650 days (as sros2: a peer whose
clock is a little behind does not see them in the future); the permissions' validity is the
certificate's. Signatures are S/MIME clear-signed (detached, text/plain, SHA-256), the form
`openssl smime -sign -text` writes and every DDS-Security plugin reads.

A policy (sros2's format, version 0.2.0) grants each enclave's profiles; ROS names become DDS
topics as sros2's permissions.xsl does: topics rt<fqn>; a service's requester publishes
rq<fqn>Request and subscribes rr<fqn>Reply, its replier the reverse; actions their five topics;
`~name` is <ns>/<node>/name, a relative name <ns>/name. Like sros2 under rmw_fastrtps_cpp and
rmw_cyclonedds_cpp, every grant also allows ros_discovery_info. The topics of a rule are sorted
and deduplicated (sros2 sorts them by group; the set granted is the same).

Cost: a few openssl processes per certificate (tens of ms). Errors name the file or element
and exit 1; nothing is left half-written where a step fails before the signature.
"""

import argparse
import datetime
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from xml.etree import ElementInclude
from xml.sax.saxutils import escape, quoteattr

PUBLIC, PRIVATE, ENCLAVES = "public", "private", "enclaves"
DEFAULT_CN = "sros2CA"
KINDS = ("ENCRYPT", "SIGN", "NONE")
# sros2's governance template (policy/defaults/dds/governance.xml).
DEFAULT_GOVERNANCE = {
    "discovery": "ENCRYPT",
    "liveliness": "ENCRYPT",
    "rtps": "SIGN",
    "metadata": "ENCRYPT",
    "data": "ENCRYPT",
}
VALID_BEFORE = datetime.timedelta(days=1)
VALID_FOR = datetime.timedelta(days=3650)
POLICY_VERSION = "0.2.0"
XSI = 'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"'
SCHEMA = "http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_{}.xsd"


class KeystoreError(Exception):
    """What went wrong, naming the file, enclave or element the user has to fix."""


# ---------------------------------------------------------------- openssl


def openssl(*args, cwd=None):
    """Runs openssl; its stderr becomes the error (openssl names the file it could not read)."""
    try:
        done = subprocess.run(["openssl", *args], cwd=cwd, capture_output=True, text=True)
    except FileNotFoundError as e:
        raise KeystoreError("the openssl command is not installed (apt-get install openssl)") from e
    if done.returncode != 0:
        raise KeystoreError(f"openssl {args[0]} failed: {done.stderr.strip()}")
    return done.stdout


def new_key(path):
    """An EC prime256v1 key (DDS-Security 9.3.1), PKCS#8 PEM, readable by its owner only."""
    openssl("genpkey", "-algorithm", "EC", "-pkeyopt", "ec_paramgen_curve:P-256",
            "-pkeyopt", "ec_param_enc:named_curve", "-out", str(path))
    os.chmod(path, 0o600)


def issue(cn, key, cert, ca_cert=None, ca_key=None):
    """Writes `cert` for `key` with subject CN=`cn`: self-signed CA when ca_cert is None.

    `openssl ca` rather than `openssl x509` because only it sets a start date in the past (the
    day of slack sros2 gives) on OpenSSL 3.0; its database lives in a temporary folder.
    """
    now = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
    start, end = now - VALID_BEFORE, now + VALID_FOR
    constraints = "critical, CA:TRUE, pathlen:1" if ca_cert is None else "CA:FALSE"
    with tempfile.TemporaryDirectory() as tmp:
        t = pathlib.Path(tmp)
        (t / "index.txt").write_text("")
        (t / "req.cnf").write_text(
            f"[req]\nprompt = no\nutf8 = yes\ndistinguished_name = dn\n[dn]\nCN = {cn}\n")
        (t / "ca.cnf").write_text(
            "[ca]\ndefault_ca = this\n[this]\n"
            f"database = {t / 'index.txt'}\nnew_certs_dir = {t}\nrand_serial = yes\n"
            "default_md = sha256\npolicy = any\nunique_subject = no\nemail_in_dn = no\n"
            "copy_extensions = none\n[any]\ncommonName = supplied\n"
            f"[ext]\nbasicConstraints = {constraints}\n"
            # sros2's certificates carry no key identifiers (OpenSSL 3 adds them by default).
            "subjectKeyIdentifier = none\nauthorityKeyIdentifier = none\n")
        openssl("req", "-new", "-config", str(t / "req.cnf"), "-key", str(key),
                "-out", str(t / "req.pem"))
        signer = ["-selfsign", "-keyfile", str(key)] if ca_cert is None else [
            "-cert", str(ca_cert), "-keyfile", str(ca_key)]
        openssl("ca", "-batch", "-config", str(t / "ca.cnf"), *signer, "-in", str(t / "req.pem"),
                "-out", str(t / "cert.pem"), "-notext", "-preserveDN", "-extensions", "ext",
                "-startdate", start.strftime("%Y%m%d%H%M%SZ"),
                "-enddate", end.strftime("%Y%m%d%H%M%SZ"))
        pathlib.Path(cert).write_bytes((t / "cert.pem").read_bytes())


def validity(cert):
    """The certificate's notBefore and notAfter as sros2 writes them (ISO 8601, UTC, no zone)."""
    out = openssl("x509", "-in", str(cert), "-noout", "-startdate", "-enddate")
    dates = dict(line.split("=", 1) for line in out.strip().splitlines())
    fmt = "%b %d %H:%M:%S %Y %Z"
    return tuple(
        datetime.datetime.strptime(" ".join(dates[k].split()), fmt).isoformat()
        for k in ("notBefore", "notAfter"))


def smime_sign(ca_cert, ca_key, document, signed):
    """`signed` := S/MIME clear-signed `document` (detached, text/plain, SHA-256)."""
    openssl("smime", "-sign", "-text", "-md", "sha256", "-in", str(document),
            "-signer", str(ca_cert), "-inkey", str(ca_key), "-out", str(signed))


# ---------------------------------------------------------------- keystore


def link(target, dst):
    """dst -> target (a relative link, as sros2 makes them), replacing what was there."""
    dst = pathlib.Path(dst)
    if dst.is_symlink() or dst.exists():
        dst.unlink()
    os.symlink(target, dst)


def is_keystore(ks):
    return all((ks / p).is_file() for p in (
        f"{PUBLIC}/permissions_ca.cert.pem", f"{PUBLIC}/identity_ca.cert.pem",
        f"{PRIVATE}/permissions_ca.key.pem", f"{PRIVATE}/identity_ca.key.pem",
        f"{ENCLAVES}/governance.p7s"))


def require_keystore(ks):
    if not is_keystore(ks):
        raise KeystoreError(f"{ks} is not a keystore (make it with create_keystore)")


def ca_paths(ks, role):
    return ks / PUBLIC / f"{role}_ca.cert.pem", ks / PRIVATE / f"{role}_ca.key.pem"


def create_keystore(ks, common_name, separate, domain_id, governance):
    if is_keystore(ks):
        raise KeystoreError(f"{ks} already holds a keystore")
    if not re.fullmatch(r"[A-Za-z0-9_. -]+", common_name):
        raise KeystoreError(f"--common-name {common_name!r}: letters, digits, _ . - and space")
    for d in (ks / PUBLIC, ks / PRIVATE, ks / ENCLAVES):
        d.mkdir(parents=True, exist_ok=True)
    new_key(ks / PRIVATE / "ca.key.pem")
    issue(common_name, ks / PRIVATE / "ca.key.pem", ks / PUBLIC / "ca.cert.pem")
    link("ca.cert.pem", ks / PUBLIC / "identity_ca.cert.pem")
    link("ca.key.pem", ks / PRIVATE / "identity_ca.key.pem")
    if separate:
        # Two roles, two keys: the layout sros2 uses when the user supplies both CAs.
        cert, key = ca_paths(ks, "permissions")
        new_key(key)
        issue(f"{common_name} permissions", key, cert)
    else:
        link("ca.cert.pem", ks / PUBLIC / "permissions_ca.cert.pem")
        link("ca.key.pem", ks / PRIVATE / "permissions_ca.key.pem")
    create_governance(ks, domain_id, governance)


def governance_xml(domain_id, g, allow_unauthenticated, join_access_control):
    flag = lambda b: "true" if b else "false"  # noqa: E731
    return f"""<dds {XSI}
    xsi:noNamespaceSchemaLocation="{SCHEMA.format('governance')}">
    <domain_access_rules>
        <domain_rule>
            <domains>
              <id>{domain_id}</id>
            </domains>
            <allow_unauthenticated_participants>{flag(allow_unauthenticated)}</allow_unauthenticated_participants>
            <enable_join_access_control>{flag(join_access_control)}</enable_join_access_control>
            <discovery_protection_kind>{g['discovery']}</discovery_protection_kind>
            <liveliness_protection_kind>{g['liveliness']}</liveliness_protection_kind>
            <rtps_protection_kind>{g['rtps']}</rtps_protection_kind>
            <topic_access_rules>
                <topic_rule>
                    <topic_expression>*</topic_expression>
                    <enable_discovery_protection>true</enable_discovery_protection>
                    <enable_liveliness_protection>true</enable_liveliness_protection>
                    <enable_read_access_control>true</enable_read_access_control>
                    <enable_write_access_control>true</enable_write_access_control>
                    <metadata_protection_kind>{g['metadata']}</metadata_protection_kind>
                    <data_protection_kind>{g['data']}</data_protection_kind>
                </topic_rule>
            </topic_access_rules>
        </domain_rule>
    </domain_access_rules>
</dds>
"""


def create_governance(ks, domain_id, governance):
    kinds, allow_unauthenticated, join_access_control = governance
    path = ks / ENCLAVES / "governance.xml"
    path.write_text(governance_xml(domain_id, kinds, allow_unauthenticated, join_access_control))
    smime_sign(*ca_paths(ks, "permissions"), path, ks / ENCLAVES / "governance.p7s")


# ---------------------------------------------------------------- enclaves


def check_enclave_name(name):
    """rclpy's validate_namespace, which sros2 applies to enclave names."""
    if name == "/":
        return
    ok = (name.startswith("/") and not name.endswith("/") and "//" not in name
          and re.fullmatch(r"[A-Za-z0-9_/]+", name)
          and not any(t[:1].isdigit() for t in name.split("/")))
    if not ok:
        raise KeystoreError(f"enclave name {name!r} is not a valid ROS namespace "
                            "(absolute, tokens of letters, digits and _, not starting with a digit)")


def enclave_dir(ks, name):
    check_enclave_name(name)
    return ks / ENCLAVES / os.path.normpath(name.lstrip("/") or ".")


def create_enclave(ks, name, domain_id):
    require_keystore(ks)
    d = enclave_dir(ks, name)
    d.mkdir(parents=True, exist_ok=True)
    for role in ("identity", "permissions"):
        link(os.path.relpath(ks / PUBLIC / f"{role}_ca.cert.pem", d), d / f"{role}_ca.cert.pem")
    link(os.path.relpath(ks / ENCLAVES / "governance.p7s", d), d / "governance.p7s")
    if not (d / "cert.pem").is_file() or not (d / "key.pem").is_file():
        new_key(d / "key.pem")
        issue(name, d / "key.pem", d / "cert.pem", *ca_paths(ks, "identity"))
    # sros2's default: everything allowed, until create_permission applies a policy.
    wildcard = [{"ns": "/", "node": "default", "rules": [
        ("topics", {"publish": "ALLOW", "subscribe": "ALLOW"}, ["/*"]),
        ("services", {"reply": "ALLOW", "request": "ALLOW"}, ["/*"]),
        ("actions", {"call": "ALLOW", "execute": "ALLOW"}, ["/*"]),
    ]}]
    write_permissions(ks, name, [wildcard], domain_id)


# ---------------------------------------------------------------- policy


def load_policy(path):
    """{enclave path: [profiles]} from an sros2 policy file (XInclude resolved), checked as
    policy.xsd would; a profile is {"ns", "node", "rules": [(kind, {verb: ALLOW|DENY}, names)]}."""
    path = pathlib.Path(path)
    try:
        tree = ET.parse(path)
        root = tree.getroot()
        ElementInclude.include(root, base_url=str(path.resolve()))
    except (OSError, ET.ParseError, ElementInclude.FatalIncludeError) as e:
        raise KeystoreError(f"policy {path}: {e}") from e
    where = f"policy {path}"
    if root.tag != "policy" or root.get("version") != POLICY_VERSION:
        raise KeystoreError(f'{where}: the root must be <policy version="{POLICY_VERSION}">')
    verbs = {"topics": ("topic", ("publish", "subscribe")),
             "services": ("service", ("request", "reply")),
             "actions": ("action", ("call", "execute"))}
    enclaves = {}
    for enclave in root.findall("enclaves/enclave"):
        name = enclave.get("path")
        if name is None:
            raise KeystoreError(f"{where}: an <enclave> without path")
        check_enclave_name(name)
        groups = enclaves.setdefault(name, [])
        for profiles in enclave.findall("profiles"):
            group = []
            for profile in profiles.findall("profile"):
                ns, node = profile.get("ns"), profile.get("node")
                if ns is None or node is None:
                    raise KeystoreError(f"{where}: enclave {name}: a <profile> needs ns and node")
                rules = []
                for rule in profile:
                    if rule.tag not in verbs:
                        raise KeystoreError(f"{where}: enclave {name} profile {ns} {node}: "
                                            f"unknown element <{rule.tag}>")
                    item, allowed = verbs[rule.tag]
                    quals = {}
                    for verb, q in rule.attrib.items():
                        if verb not in allowed or q not in ("ALLOW", "DENY"):
                            raise KeystoreError(
                                f"{where}: enclave {name} profile {ns} {node}: <{rule.tag} "
                                f'{verb}="{q}">: expected {" or ".join(allowed)} = ALLOW or DENY')
                        quals[verb] = q
                    names = [(e.text or "").strip() for e in rule.findall(item)]
                    if not names or "" in names:
                        raise KeystoreError(f"{where}: enclave {name} profile {ns} {node}: "
                                            f"<{rule.tag}> needs non-empty <{item}> elements")
                    rules.append((rule.tag, quals, names))
                group.append({"ns": ns, "node": node, "rules": rules})
            groups.append(group)
    if not enclaves:
        raise KeystoreError(f"{where}: no <enclaves>/<enclave>")
    return enclaves


def fqn(name, ns, node):
    """sros2's name expansion: absolute as is, ~ private to the node, else in the namespace."""
    ns = ns if ns.endswith("/") else ns + "/"
    if name.startswith("/"):
        return name
    if name.startswith("~"):
        return ns + node + name[1:]
    return ns + name


def dds_topics(kind, verb, name):
    """(published, subscribed) DDS topic names for one granted ROS name (permissions.xsl)."""
    if kind == "topics":
        return ([f"rt{name}"], []) if verb == "publish" else ([], [f"rt{name}"])
    if kind == "services":
        req, rep = [f"rq{name}Request"], [f"rr{name}Reply"]
        return (req, rep) if verb == "request" else (rep, req)
    requests = [f"rq{name}/_action/{g}Request" for g in ("cancel_goal", "get_result", "send_goal")]
    replies = [f"rr{name}/_action/{g}Reply" for g in ("cancel_goal", "get_result", "send_goal")]
    replies += [f"rt{name}/_action/feedback", f"rt{name}/_action/status"]
    return (requests, replies) if verb == "call" else (replies, requests)


def rule_xml(tag, domain_id, publish, subscribe):
    lines = [f"      <{tag}>", "        <domains>", f"          <id>{domain_id}</id>",
             "        </domains>"]
    for section, topics in (("publish", publish), ("subscribe", subscribe)):
        if topics:
            lines += [f"        <{section}>", "          <topics>"]
            lines += [f"            <topic>{escape(t)}</topic>" for t in sorted(set(topics))]
            lines += ["          </topics>", f"        </{section}>"]
    return lines + [f"      </{tag}>"]


def permissions_xml(name, groups, domain_id, not_before, not_after, discovery_topic=True):
    lines = [f'<dds {XSI} xsi:noNamespaceSchemaLocation="{SCHEMA.format("permissions")}">',
             "  <permissions>"]
    for group in groups:
        grant = {"DENY": ([], []), "ALLOW": ([], [])}
        for profile in group:
            for kind, quals, names in profile["rules"]:
                for verb, q in quals.items():
                    for n in names:
                        pub, sub = dds_topics(kind, verb, fqn(n, profile["ns"], profile["node"]))
                        grant[q][0].extend(pub)
                        grant[q][1].extend(sub)
        lines += [f"    <grant name={quoteattr(name)}>",
                  f"      <subject_name>CN={escape(name)}</subject_name>",
                  "      <validity>", f"        <not_before>{not_before}</not_before>",
                  f"        <not_after>{not_after}</not_after>", "      </validity>"]
        for q, tag in (("DENY", "deny_rule"), ("ALLOW", "allow_rule")):
            if any(grant[q]):
                lines += rule_xml(tag, domain_id, *grant[q])
        if discovery_topic:
            lines += rule_xml("allow_rule", domain_id, ["ros_discovery_info"],
                              ["ros_discovery_info"])
        lines += ["      <default>DENY</default>", "    </grant>"]
    return "\n".join(lines + ["  </permissions>", "</dds>", ""])


def write_permissions(ks, name, groups, domain_id):
    d = enclave_dir(ks, name)
    if not (d / "cert.pem").is_file():
        raise KeystoreError(f"enclave {name}: {d / 'cert.pem'} missing (create_enclave first)")
    xml = permissions_xml(name, groups, domain_id, *validity(d / "cert.pem"))
    (d / "permissions.xml").write_text(xml)
    smime_sign(*ca_paths(ks, "permissions"), d / "permissions.xml", d / "permissions.p7s")


def create_permission(ks, name, policy, domain_id):
    require_keystore(ks)
    enclaves = load_policy(policy)
    if name not in enclaves:
        raise KeystoreError(f"policy {policy}: no enclave {name!r} (it has: "
                            f"{', '.join(sorted(enclaves))})")
    write_permissions(ks, name, enclaves[name], domain_id)


def list_enclaves(ks):
    require_keystore(ks)
    root = ks / ENCLAVES
    return sorted("/" + str(k.parent.relative_to(root)).replace(os.sep, "/")
                  for k in root.glob("**/key.pem"))


# ---------------------------------------------------------------- command line


def governance_args(p):
    p.add_argument("--protection", choices=KINDS, help="all five protection kinds at once")
    for k, v in DEFAULT_GOVERNANCE.items():
        p.add_argument(f"--{k}-protection", choices=KINDS, default=None,
                       help=f"{k}_protection_kind (sros2: {v})")
    p.add_argument("--allow-unauthenticated-participants", action="store_true")
    p.add_argument("--no-join-access-control", action="store_true",
                   help="enable_join_access_control false (sros2: true)")


def governance_of(a):
    kinds = {k: getattr(a, f"{k}_protection") or a.protection or v
             for k, v in DEFAULT_GOVERNANCE.items()}
    return kinds, a.allow_unauthenticated_participants, not a.no_join_access_control


def parser():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--domain-id", default=os.environ.get("ROS_DOMAIN_ID", "0"),
                   help="the DDS domain of governance and permissions (ROS_DOMAIN_ID, else 0)")
    sub = p.add_subparsers(dest="verb", required=True)
    c = sub.add_parser("create_keystore", help="a new CA, governance and enclaves folder")
    c.add_argument("keystore")
    c.add_argument("--common-name", default=DEFAULT_CN, help=f"the CA's CN (sros2: {DEFAULT_CN})")
    c.add_argument("--separate-permissions-ca", action="store_true",
                   help="a second CA for governance and permissions instead of links to the one")
    governance_args(c)
    g = sub.add_parser("create_governance", help="rewrite and re-sign KS's governance")
    g.add_argument("keystore")
    governance_args(g)
    e = sub.add_parser("create_enclave", help="a key, certificate and wildcard permissions")
    e.add_argument("keystore")
    e.add_argument("name")
    m = sub.add_parser("create_permission", help="an enclave's permissions from a policy")
    m.add_argument("keystore")
    m.add_argument("name")
    m.add_argument("policy")
    a = sub.add_parser("generate_artifacts",
                       help="keystore (if absent), then every enclave of the policy with its "
                            "permissions (or only those named)")
    a.add_argument("keystore")
    a.add_argument("policy")
    a.add_argument("enclaves", nargs="*")
    governance_args(a)
    s = sub.add_parser("list_enclaves")
    s.add_argument("keystore")
    return p


def main(argv):
    a = parser().parse_args(argv)
    ks = pathlib.Path(a.keystore)
    if not re.fullmatch(r"[0-9]+", str(a.domain_id)) or int(a.domain_id) > 232:
        raise KeystoreError(f"domain id {a.domain_id!r}: an integer 0..232")
    if a.verb == "create_keystore":
        create_keystore(ks, a.common_name, a.separate_permissions_ca, a.domain_id,
                        governance_of(a))
    elif a.verb == "create_governance":
        require_keystore(ks)
        create_governance(ks, a.domain_id, governance_of(a))
    elif a.verb == "create_enclave":
        create_enclave(ks, a.name, a.domain_id)
    elif a.verb == "create_permission":
        create_permission(ks, a.name, a.policy, a.domain_id)
    elif a.verb == "generate_artifacts":
        enclaves = load_policy(a.policy)
        if not is_keystore(ks):
            create_keystore(ks, DEFAULT_CN, False, a.domain_id, governance_of(a))
        for name in a.enclaves or sorted(enclaves):
            create_enclave(ks, name, a.domain_id)
            create_permission(ks, name, a.policy, a.domain_id)
    else:
        print("\n".join(list_enclaves(ks)))


if __name__ == "__main__":
    try:
        main(sys.argv[1:])
    except KeystoreError as e:
        print(f"sros2_keystore: {e}", file=sys.stderr)
        sys.exit(1)
