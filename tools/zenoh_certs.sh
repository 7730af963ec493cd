#!/usr/bin/env bash
# Makes the certificates of a zenoh cell secured by mTLS (docs/security.md, "zenoh"): a CA and,
# for each NAME, a key and a certificate that this CA signs, with NAME as its common name (the
# name by which the router's access control, `cert_common_names`, knows that session).
#
#   tools/zenoh_certs.sh DIR NAME...
#   tools/zenoh_certs.sh certs router ist_monitor camera robot hmi
#
# Writes DIR/ca.pem and DIR/ca.key (the CA; made only if DIR/ca.key is absent, so that names can
# be added later), then DIR/NAME.pem and DIR/NAME.key for each NAME. Every certificate names the
# hosts of ZENOH_CERT_SAN (default `DNS:localhost,IP:127.0.0.1`) as its subjectAltName: a session
# that connects to `tls/HOST:7447` checks that the router's certificate names HOST, so set it to
# the router's host name when the router is not on this machine. Keys are ECDSA P-256, valid
# ZENOH_CERT_DAYS days (default 365). Only the `openssl` command line is needed. Keep the *.key
# files (ca.key above all) readable by their owner only: whoever has ca.key can make members.
set -euo pipefail
if [[ $# -lt 2 ]]; then
  echo "usage: $0 DIR NAME..." >&2
  exit 2
fi
dir=$1
shift
san=${ZENOH_CERT_SAN:-DNS:localhost,IP:127.0.0.1}
days=${ZENOH_CERT_DAYS:-365}
mkdir -p "$dir"
umask 077
if [[ ! -f "$dir/ca.key" ]]; then
  openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -sha256 \
    -days "$days" -subj "/CN=zenoh cell CA" \
    -addext "basicConstraints=critical,CA:TRUE" \
    -addext "keyUsage=critical,keyCertSign,cRLSign" \
    -keyout "$dir/ca.key" -out "$dir/ca.pem" 2>/dev/null
fi
ext=$(mktemp)
trap 'rm -f "$ext" "$dir"/*.csr' EXIT
cat >"$ext" <<EOF
basicConstraints=critical,CA:FALSE
keyUsage=critical,digitalSignature,keyEncipherment
extendedKeyUsage=serverAuth,clientAuth
subjectAltName=$san
EOF
for name in "$@"; do
  if [[ ! "$name" =~ ^[A-Za-z0-9_.-]+$ ]]; then
    echo "$0: '$name': a name is letters, digits, '_', '.' and '-' (it becomes a file name)" >&2
    exit 2
  fi
  openssl req -new -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -sha256 \
    -subj "/CN=$name" -keyout "$dir/$name.key" -out "$dir/$name.csr" 2>/dev/null
  openssl x509 -req -in "$dir/$name.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" \
    -CAcreateserial -days "$days" -sha256 -extfile "$ext" -out "$dir/$name.pem" 2>/dev/null
  chmod 644 "$dir/$name.pem"
done
chmod 644 "$dir/ca.pem"
rm -f "$dir/ca.srl"
