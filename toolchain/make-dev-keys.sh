#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# A development CA and a signing certificate it issued, for update bundles
# made and installed in tests. Never for a head in the field: its key sits
# next to it in the clear (docs/image.md, "Signing keys").
#   toolchain/make-dev-keys.sh DIR [NAME]
# Writes DIR/ca.cert.pem (the keyring an image trusts), DIR/ca.key.pem,
# DIR/signing.cert.pem and DIR/signing.key.pem.
set -euo pipefail
if [ $# -lt 1 ] || [ $# -gt 2 ]; then
  echo "usage: toolchain/make-dev-keys.sh DIR [NAME]" >&2
  exit 2
fi
dir=$1
name=${2:-cylscan development}
mkdir -p "$dir"
cd "$dir"
ec=(-newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes)
openssl req -x509 "${ec[@]}" -keyout ca.key.pem -out ca.cert.pem -days 3650 -subj "/CN=$name CA" \
  -addext basicConstraints=critical,CA:TRUE -addext keyUsage=critical,keyCertSign,cRLSign 2>/dev/null
openssl req "${ec[@]}" -keyout signing.key.pem -out signing.csr.pem -subj "/CN=$name signing" 2>/dev/null
printf 'basicConstraints=critical,CA:FALSE\nkeyUsage=critical,digitalSignature\n' >signing.ext
openssl x509 -req -in signing.csr.pem -CA ca.cert.pem -CAkey ca.key.pem -CAcreateserial -days 3650 \
  -extfile signing.ext -out signing.cert.pem 2>/dev/null
rm -f signing.csr.pem signing.ext ca.cert.srl
chmod 0600 ca.key.pem signing.key.pem
echo "$dir"
