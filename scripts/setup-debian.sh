#!/usr/bin/env bash
# Installs the Debian packages the tests need (idempotent): libtbb12, which ecos (the `ecospy`
# package, the second FMU importer of fmu/tests/importers/) links against.
# scripts/setup.sh calls it (CI runs as root on a fresh Debian machine; as another user it uses sudo).
set -euo pipefail
packages=(libtbb12)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -eq 0 ]; then
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  SUDO="sudo"
fi
echo "setup-debian: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
