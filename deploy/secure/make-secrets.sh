#!/usr/bin/env bash
# Makes the secrets of the secure deployment (deploy/secure/README.md) in DIR and
# writes the server's and the two roles' Zenoh configurations there:
#   ca.pem ca.key            a private certificate authority (keep ca.key offline)
#   server.pem server.key    the server's TLS certificate (CN and SAN: localhost, 127.0.0.1,
#                            and HOSTS, a comma-separated list of more DNS names)
#   users.txt                user:password lines: "writer" and "reader", random passwords
#   server.json5             deploy/secure/server.json5 with DIR filled in
#   writer.json5 reader.json5  client configurations with DIR and the passwords filled in
# Usage: deploy/secure/make-secrets.sh DIR [HOSTS]
# Needs openssl. Refuses to overwrite an existing DIR/ca.key.
set -euo pipefail
dir=${1:?usage: make-secrets.sh DIR [HOSTS]}
hosts=${2:-}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$dir"
dir=$(cd "$dir" && pwd)
if [[ -e "$dir/ca.key" ]]; then
  echo "make-secrets.sh: $dir/ca.key exists; not overwriting" >&2
  exit 1
fi
umask 077
cd "$dir"
openssl req -x509 -newkey rsa:2048 -nodes -keyout ca.key -out ca.pem -days 825 \
  -subj "/CN=riskplan-ca" 2>/dev/null
openssl req -newkey rsa:2048 -nodes -keyout server.key -out server.csr -subj "/CN=localhost" 2>/dev/null
san="DNS:localhost,IP:127.0.0.1"
IFS=',' read -ra extra <<< "$hosts"
for h in "${extra[@]}"; do [[ -n "$h" ]] && san="$san,DNS:$h"; done
printf "subjectAltName=%s\nbasicConstraints=CA:FALSE\nkeyUsage=digitalSignature,keyEncipherment\nextendedKeyUsage=serverAuth\n" \
  "$san" > server.ext
openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out server.pem -days 825 \
  -extfile server.ext 2>/dev/null
rm -f server.csr server.ext ca.srl
pw() { openssl rand -hex 16; }
writer_pw=$(pw)
reader_pw=$(pw)
printf "writer:%s\nreader:%s\n" "$writer_pw" "$reader_pw" > users.txt
fill() { sed -e "s|@SECRETS@|$dir|g" -e "s|@USER@|$2|g" -e "s|@PASSWORD@|$3|g" "$here/$1"; }
fill server.json5 "" "" > server.json5
fill client.json5 writer "$writer_pw" > writer.json5
fill client.json5 reader "$reader_pw" > reader.json5
chmod 644 ca.pem server.pem
echo "make-secrets.sh: wrote $dir/{ca.pem,ca.key,server.pem,server.key,users.txt,server.json5,writer.json5,reader.json5}"
