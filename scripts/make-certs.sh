#!/usr/bin/env bash
# Certificates and credential for one co-simulation run across two hosts (docs/two-hosts/).
#
#   scripts/make-certs.sh OUT_DIR RUN_ID PLANT_ADDRESS [MORE_PLANT_ADDRESSES...]
#
# creates, with openssl, in OUT_DIR (mode 0700):
#   ca.pem                  the run's own certificate authority (its key is deleted after signing,
#                           so nobody can issue another certificate for this run)
#   plant.pem, plant.key    host A's certificate: the plant's router listens with it; valid for
#                           PLANT_ADDRESS (an IP address or a host name) and any more given
#   client.pem, client.key  the certificate a controller or recorder presents (mutual TLS)
#   credential              the run's credential (crawler-credential 1: run id and a 256-bit
#                           secret), which seals every message of the run
# Keys and the credential are mode 0600. Copy ca.pem, client.pem, client.key and credential to
# host B (e.g. scp -p), and nothing else. A certificate of another run (another CA) cannot join
# this run; a session without a valid certificate cannot connect.
set -euo pipefail

if [ $# -lt 3 ]; then
    sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
fi
out=$1
run=$2
shift 2
if ! [[ $run =~ ^[A-Za-z0-9_-]{1,64}$ ]]; then
    echo "make-certs.sh: invalid run id '$run': allowed 1 to 64 characters from A-Z a-z 0-9 _ -" >&2
    exit 2
fi
command -v openssl > /dev/null || { echo "make-certs.sh: openssl is needed" >&2; exit 1; }
days=${CRAWLER_CERT_DAYS:-30}

umask 077
mkdir -p "$out"
chmod 700 "$out"
for f in ca.pem plant.pem plant.key client.pem client.key credential; do
    if [ -e "$out/$f" ]; then
        echo "make-certs.sh: $out/$f exists; refusing to overwrite it (use a new directory)" >&2
        exit 1
    fi
done

san=""
for a in "$@"; do
    if [[ $a =~ ^[0-9.]+$ || $a == *:* ]]; then
        san+="IP:$a,"
    else
        san+="DNS:$a,"
    fi
done
san=${san%,}

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

key() { openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$1" 2> /dev/null; }

# The run's CA.
key "$work/ca.key"
openssl req -x509 -new -key "$work/ca.key" -sha256 -days "$days" -subj "/CN=crawler run $run CA" \
    -addext "basicConstraints=critical,CA:TRUE,pathlen:0" \
    -addext "keyUsage=critical,keyCertSign,cRLSign" -out "$out/ca.pem"

# issue NAME CN EXTENSIONS: a key and a certificate signed by the run's CA.
issue() {
    key "$out/$1.key"
    openssl req -new -key "$out/$1.key" -subj "/CN=$2" -out "$work/$1.csr"
    printf '%s\n' "$3" > "$work/$1.ext"
    openssl x509 -req -in "$work/$1.csr" -CA "$out/ca.pem" -CAkey "$work/ca.key" -CAcreateserial \
        -CAserial "$work/ca.srl" \
        -sha256 -days "$days" -extfile "$work/$1.ext" -out "$out/$1.pem" 2> /dev/null
}
issue plant "crawler-$run-plant" "basicConstraints=critical,CA:FALSE
keyUsage=critical,digitalSignature
extendedKeyUsage=serverAuth,clientAuth
subjectAltName=$san"
issue client "crawler-$run-client" "basicConstraints=critical,CA:FALSE
keyUsage=critical,digitalSignature
extendedKeyUsage=clientAuth"

# The run's credential (the format crawler-plant writes itself).
printf 'crawler-credential 1\nrun %s\nsecret %s\n' "$run" "$(openssl rand -hex 32)" > "$out/credential"
chmod 600 "$out"/*.key "$out/credential"
chmod 644 "$out"/*.pem

echo "make-certs.sh: run $run: certificates and credential in $out (plant valid for: $san; $days days)"
