#!/usr/bin/env bash
# Installs the Debian packages the tests need (idempotent): libtbb12, which ecos (the `ecospy`
# package, the second FMU importer of fmu/tests/importers/) links against.
# .ci/run calls it; CI runs as root on a fresh Debian machine. Elsewhere, run it with sudo.
set -euo pipefail
packages=(libtbb12)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -eq 0 ]; then
  exit 0
fi
if [ "$(id -u)" -ne 0 ]; then
  echo "setup-debian: missing Debian packages ${missing[*]}: run sudo $0" >&2
  exit 1
fi
echo "setup-debian: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}"
