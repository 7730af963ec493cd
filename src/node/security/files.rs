//! An enclave's six files, checked before RustDDS is given them, so that a refusal names the
//! file: input the enclave's folder; output the first file missing, or the first that does not
//! parse or does not fit the others. Cost: a few file reads and signature checks (ECDSA or RSA,
//! well under a millisecond each), once at start.
//!
//! The checks (OpenSSL, which RustDDS's security already links): the certificates are PEM X.509
//! and valid today; `cert.pem` is signed by `identity_ca.cert.pem`; `key.pem` is an unencrypted
//! PKCS#8 key (what RustDDS reads; rcl passes no password) and is the key of `cert.pem`;
//! `governance.p7s` and `permissions.p7s` are S/MIME signed by `permissions_ca.cert.pem` and
//! hold a governance (`<domain_access_rules>`) and a permissions (`<permissions>`) document.
//! What they say (the rules, the grant's subject) is left to RustDDS, whose refusal is
//! reported with its own message, but for one rule RustDDS 0.15.1 cannot keep: payload
//! protection (`data_protection_kind` ENCRYPT or SIGN) of a sample large enough to be sent in
//! fragments (a cloud). RustDDS transforms each DATA_FRAG's slice instead of the whole payload,
//! so the slices outgrow the fragment sizes the submessage declares and every receiver drops
//! them: such a topic carries nothing. [`check_files`] reports the rule, for a WARN;
//! `metadata_protection_kind` ENCRYPT with `data_protection_kind` NONE encrypts the same bytes
//! (the whole submessage) and works.

use std::path::{Path, PathBuf};

/// The files of an enclave, as rmw_dds_common's `get_security_files` names them.
pub const ENCLAVE_FILES: [&str; 6] = [
    "identity_ca.cert.pem",
    "cert.pem",
    "key.pem",
    "permissions_ca.cert.pem",
    "governance.p7s",
    "permissions.p7s",
];

/// The first of the enclave's files (in [`ENCLAVE_FILES`]' order) that `dir` lacks.
pub fn first_missing(dir: &Path) -> Option<PathBuf> {
    ENCLAVE_FILES
        .iter()
        .map(|f| dir.join(f))
        .find(|p| !p.is_file())
}

/// A file of the enclave that is unusable, and why.
#[derive(Debug)]
pub struct BadFile {
    pub file: PathBuf,
    pub why: String,
}

#[cfg(feature = "security")]
pub use checks::check_files;

#[cfg(feature = "security")]
mod checks {
    use std::path::Path;

    use openssl::asn1::Asn1Time;
    use openssl::pkcs7::{Pkcs7, Pkcs7Flags};
    use openssl::pkey::PKey;
    use openssl::stack::Stack;
    use openssl::x509::store::X509StoreBuilder;
    use openssl::x509::X509;

    use super::BadFile;

    /// The enclave's files in `dir` (all present) checked one by one; the first unusable one.
    /// `Ok(true)`: the governance asks for payload protection (`data_protection_kind` ENCRYPT
    /// or SIGN), which RustDDS cannot apply to fragmented samples (the module's doc).
    pub fn check_files(dir: &Path) -> Result<bool, BadFile> {
        let identity_ca = certificate(dir, "identity_ca.cert.pem")?;
        let cert = certificate(dir, "cert.pem")?;
        let ca_key = identity_ca
            .public_key()
            .map_err(|e| bad(dir, "identity_ca.cert.pem", format!("its public key: {e}")))?;
        if !cert.verify(&ca_key).unwrap_or(false) {
            return Err(bad(
                dir,
                "cert.pem",
                "not signed by identity_ca.cert.pem (a certificate of another identity CA?)".into(),
            ));
        }
        private_key(dir, &cert)?;
        let permissions_ca = certificate(dir, "permissions_ca.cert.pem")?;
        let governance = signed_document(
            dir,
            "governance.p7s",
            &permissions_ca,
            "<domain_access_rules",
        )?;
        signed_document(dir, "permissions.p7s", &permissions_ca, "<permissions")?;
        Ok(payload_protected(&governance))
    }

    /// Whether a governance document asks for payload protection anywhere.
    pub(super) fn payload_protected(governance: &str) -> bool {
        governance
            .split("<data_protection_kind>")
            .skip(1)
            .any(|rest| matches!(rest.trim_start().get(..4), Some("ENCR" | "SIGN")))
    }

    fn bad(dir: &Path, file: &str, why: String) -> BadFile {
        BadFile {
            file: dir.join(file),
            why,
        }
    }

    fn read(dir: &Path, file: &str) -> Result<Vec<u8>, BadFile> {
        std::fs::read(dir.join(file)).map_err(|e| bad(dir, file, format!("cannot read it: {e}")))
    }

    /// `file`, a PEM X.509 certificate valid now.
    fn certificate(dir: &Path, file: &str) -> Result<X509, BadFile> {
        let cert = X509::from_pem(&read(dir, file)?).map_err(|e| {
            bad(
                dir,
                file,
                format!("not a PEM X.509 certificate ({})", first_reason(&e)),
            )
        })?;
        let now =
            Asn1Time::days_from_now(0).map_err(|e| bad(dir, file, format!("the time now: {e}")))?;
        if cert.not_after() < now {
            return Err(bad(dir, file, format!("expired on {}", cert.not_after())));
        }
        if cert.not_before() > now {
            return Err(bad(
                dir,
                file,
                format!("not valid before {}", cert.not_before()),
            ));
        }
        Ok(cert)
    }

    /// `key.pem`, an unencrypted PKCS#8 key, the key of `cert`.
    fn private_key(dir: &Path, cert: &X509) -> Result<(), BadFile> {
        const FILE: &str = "key.pem";
        let pem = read(dir, FILE)?;
        let text = String::from_utf8_lossy(&pem);
        if text.contains("-----BEGIN ENCRYPTED PRIVATE KEY-----") {
            return Err(bad(
                dir,
                FILE,
                "encrypted: SROS2 keys are not (rcl passes no password)".into(),
            ));
        }
        if !text.contains("-----BEGIN PRIVATE KEY-----") {
            return Err(bad(
                dir,
                FILE,
                "not a PKCS#8 private key ('BEGIN PRIVATE KEY'), which RustDDS reads (an 'EC \
                 PRIVATE KEY' converts with `openssl pkcs8 -topk8 -nocrypt`)"
                    .into(),
            ));
        }
        let key = PKey::private_key_from_pem(&pem).map_err(|e| {
            bad(
                dir,
                FILE,
                format!("not a readable private key ({})", first_reason(&e)),
            )
        })?;
        let public = cert
            .public_key()
            .map_err(|e| bad(dir, "cert.pem", format!("its public key: {e}")))?;
        if !public.public_eq(&key) {
            return Err(bad(dir, FILE, "not the key of cert.pem".into()));
        }
        Ok(())
    }

    /// `file`, S/MIME signed by `ca` around a document that holds `root`: the document.
    fn signed_document(dir: &Path, file: &str, ca: &X509, root: &str) -> Result<String, BadFile> {
        let (p7, content) = Pkcs7::from_smime(&read(dir, file)?).map_err(|e| {
            bad(
                dir,
                file,
                format!("not an S/MIME signed document ({})", first_reason(&e)),
            )
        })?;
        let content = content.ok_or_else(|| {
            bad(
                dir,
                file,
                "not a multipart/signed S/MIME document (the XML in clear beside its signature, \
                 as DDS-Security asks)"
                    .into(),
            )
        })?;
        let store = (|| {
            let mut b = X509StoreBuilder::new()?;
            b.add_cert(ca.clone())?;
            let mut certs = Stack::new()?;
            certs.push(ca.clone())?;
            Ok::<_, openssl::error::ErrorStack>((b.build(), certs))
        })();
        let (store, certs) = store.map_err(|e| bad(dir, file, format!("OpenSSL: {e}")))?;
        let mut out = Vec::new();
        p7.verify(
            &certs,
            &store,
            Some(&content),
            Some(&mut out),
            Pkcs7Flags::TEXT,
        )
        .map_err(|e| {
            bad(
                dir,
                file,
                format!(
                    "its signature does not verify with permissions_ca.cert.pem ({})",
                    first_reason(&e)
                ),
            )
        })?;
        let document = String::from_utf8_lossy(&out).into_owned();
        if !document.contains(root) {
            return Err(bad(
                dir,
                file,
                format!("the signed document holds no {root}> element"),
            ));
        }
        Ok(document)
    }

    /// OpenSSL's first reason, short (its whole stack repeats file and line).
    fn first_reason(e: &openssl::error::ErrorStack) -> String {
        e.errors()
            .first()
            .and_then(|e| e.reason().map(String::from))
            .unwrap_or_else(|| e.to_string())
    }
}

#[cfg(all(test, feature = "security"))]
mod tests {
    use std::path::Path;

    use openssl::asn1::Asn1Time;
    use openssl::bn::BigNum;
    use openssl::ec::{EcGroup, EcKey};
    use openssl::hash::MessageDigest;
    use openssl::nid::Nid;
    use openssl::pkcs7::{Pkcs7, Pkcs7Flags};
    use openssl::pkey::{PKey, Private};
    use openssl::stack::Stack;
    use openssl::x509::extension::BasicConstraints;
    use openssl::x509::{X509Name, X509};

    use super::*;

    fn key() -> PKey<Private> {
        let group = EcGroup::from_curve_name(Nid::X9_62_PRIME256V1).unwrap();
        PKey::from_ec_key(EcKey::generate(&group).unwrap()).unwrap()
    }

    /// A certificate of `cn` for `key`, signed by `issuer` (`None`: self-signed, a CA), valid
    /// from `from_days` to `to_days` from now.
    fn cert(
        cn: &str,
        key: &PKey<Private>,
        issuer: Option<(&X509, &PKey<Private>)>,
        (from_days, to_days): (i64, i64),
    ) -> X509 {
        let mut name = X509Name::builder().unwrap();
        name.append_entry_by_text("CN", cn).unwrap();
        let name = name.build();
        let mut b = X509::builder().unwrap();
        b.set_version(2).unwrap();
        b.set_serial_number(&BigNum::from_u32(1).unwrap().to_asn1_integer().unwrap())
            .unwrap();
        b.set_subject_name(&name).unwrap();
        b.set_pubkey(key).unwrap();
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_secs() as i64;
        let at = |days: i64| Asn1Time::from_unix(now + days * 86_400).unwrap();
        b.set_not_before(&at(from_days)).unwrap();
        b.set_not_after(&at(to_days)).unwrap();
        let (issuer_name, signer) = match issuer {
            Some((c, k)) => (c.subject_name().to_owned().unwrap(), k),
            None => {
                let ca = BasicConstraints::new().critical().ca().build().unwrap();
                b.append_extension(ca).unwrap();
                (name.to_owned().unwrap(), key)
            }
        };
        b.set_issuer_name(&issuer_name).unwrap();
        b.sign(signer, MessageDigest::sha256()).unwrap();
        b.build()
    }

    /// `xml` as `openssl smime -sign -text` writes it, signed by `ca`.
    fn smime(xml: &str, ca: &X509, key: &PKey<Private>) -> Vec<u8> {
        let flags = Pkcs7Flags::DETACHED | Pkcs7Flags::TEXT;
        let p7 = Pkcs7::sign(ca, key, &Stack::new().unwrap(), xml.as_bytes(), flags).unwrap();
        p7.to_smime(xml.as_bytes(), flags).unwrap()
    }

    const GOVERNANCE: &str = "<dds><domain_access_rules></domain_access_rules></dds>";
    const PERMISSIONS: &str = "<dds><permissions><grant/></permissions></dds>";

    struct Ca(X509, PKey<Private>);

    fn ca(cn: &str) -> Ca {
        let k = key();
        Ca(cert(cn, &k, None, (-1, 365)), k)
    }

    /// A good enclave of `ca` in `dir`.
    fn enclave(dir: &Path, ca: &Ca) {
        let k = key();
        let c = cert("/cell/node", &k, Some((&ca.0, &ca.1)), (-1, 30));
        let pem = |c: &X509| c.to_pem().unwrap();
        std::fs::write(dir.join("identity_ca.cert.pem"), pem(&ca.0)).unwrap();
        std::fs::write(dir.join("permissions_ca.cert.pem"), pem(&ca.0)).unwrap();
        std::fs::write(dir.join("cert.pem"), pem(&c)).unwrap();
        std::fs::write(dir.join("key.pem"), k.private_key_to_pem_pkcs8().unwrap()).unwrap();
        let sign = |xml| smime(xml, &ca.0, &ca.1);
        std::fs::write(dir.join("governance.p7s"), sign(GOVERNANCE)).unwrap();
        std::fs::write(dir.join("permissions.p7s"), sign(PERMISSIONS)).unwrap();
    }

    /// The file and reason `check_files` gives after `spoil` changed a good enclave.
    fn refusal(spoil: impl FnOnce(&Path, &Ca)) -> (String, String) {
        let d = tempfile::tempdir().unwrap();
        let ca = ca("ca");
        enclave(d.path(), &ca);
        check_files(d.path()).unwrap();
        spoil(d.path(), &ca);
        assert_eq!(first_missing(d.path()), None);
        let bad = check_files(d.path()).unwrap_err();
        let name = bad.file.file_name().unwrap().to_string_lossy().into_owned();
        (name, bad.why)
    }

    #[test]
    fn a_good_enclave_passes_and_a_missing_file_is_named() {
        let d = tempfile::tempdir().unwrap();
        enclave(d.path(), &ca("ca"));
        assert!(!check_files(d.path()).unwrap());
        std::fs::remove_file(d.path().join("governance.p7s")).unwrap();
        assert_eq!(
            first_missing(d.path()),
            Some(d.path().join("governance.p7s"))
        );
    }

    #[test]
    fn payload_protection_is_found_in_any_rule() {
        use super::checks::payload_protected;
        let rule =
            |k: &str| format!("<topic_rule><data_protection_kind>{k}</data_protection_kind>");
        assert!(!payload_protected(&rule("NONE")));
        assert!(payload_protected(&rule("ENCRYPT")));
        assert!(payload_protected(&(rule("NONE") + &rule(" SIGN"))));
        assert!(!payload_protected(
            "<metadata_protection_kind>ENCRYPT</metadata_protection_kind>"
        ));
    }

    /// What spoils a good enclave for one case.
    type Spoil<'a> = Box<dyn FnOnce(&Path, &Ca) + 'a>;

    #[test]
    fn each_bad_file_is_named_with_why() {
        let other = ca("other ca");
        let cases: Vec<(&str, &str, Spoil)> = vec![
            (
                "identity_ca.cert.pem",
                "not a PEM X.509 certificate",
                Box::new(|d, _| std::fs::write(d.join("identity_ca.cert.pem"), "junk").unwrap()),
            ),
            (
                "cert.pem",
                "not signed by identity_ca.cert.pem",
                Box::new(|d, _| {
                    let k = key();
                    let c = cert("/x", &k, Some((&other.0, &other.1)), (-1, 30));
                    std::fs::write(d.join("cert.pem"), c.to_pem().unwrap()).unwrap();
                    std::fs::write(d.join("key.pem"), k.private_key_to_pem_pkcs8().unwrap())
                        .unwrap();
                }),
            ),
            (
                "cert.pem",
                "expired on",
                Box::new(|d, ca| {
                    let k = key();
                    let c = cert("/x", &k, Some((&ca.0, &ca.1)), (-30, -1));
                    std::fs::write(d.join("cert.pem"), c.to_pem().unwrap()).unwrap();
                }),
            ),
            (
                "key.pem",
                "not the key of cert.pem",
                Box::new(|d, _| {
                    let pem = key().private_key_to_pem_pkcs8().unwrap();
                    std::fs::write(d.join("key.pem"), pem).unwrap();
                }),
            ),
            (
                "key.pem",
                "not a PKCS#8 private key",
                Box::new(|d, _| {
                    let ec = key().ec_key().unwrap().private_key_to_pem().unwrap();
                    std::fs::write(d.join("key.pem"), ec).unwrap();
                }),
            ),
            (
                "governance.p7s",
                "does not verify with permissions_ca.cert.pem",
                Box::new(|d, _| {
                    let p7s = smime(GOVERNANCE, &other.0, &other.1);
                    std::fs::write(d.join("governance.p7s"), p7s).unwrap();
                }),
            ),
            (
                "governance.p7s",
                "holds no <domain_access_rules> element",
                Box::new(|d, ca| {
                    let p7s = smime(PERMISSIONS, &ca.0, &ca.1);
                    std::fs::write(d.join("governance.p7s"), p7s).unwrap();
                }),
            ),
            (
                "permissions.p7s",
                "not an S/MIME signed document",
                Box::new(|d, _| std::fs::write(d.join("permissions.p7s"), PERMISSIONS).unwrap()),
            ),
        ];
        for (file, why, spoil) in cases {
            let (got_file, got_why) = refusal(spoil);
            assert_eq!(got_file, file, "{got_why}");
            assert!(got_why.contains(why), "{file}: {got_why}");
        }
    }
}
