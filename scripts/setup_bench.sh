#!/usr/bin/env bash
# Extra packages for the benchmark suite only (`make bench`): Siconos numerics, the established
# complementarity library the app is compared with (Debian python3-siconos, ~22 MB with its
# dependencies). Not needed to run or test the app: if it cannot be installed the benchmark
# skips that comparison and says why. Idempotent.
set -uo pipefail
if dpkg-query -W -f='${Status}' python3-siconos 2>/dev/null | grep -q 'install ok installed'; then
  exit 0
fi
echo "setup_bench: installing python3-siconos (benchmark comparison only)"
sudo_cmd=""; [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
if ! { $sudo_cmd apt-get update -qq && DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq \
        --no-install-recommends python3-siconos >/dev/null; }; then
  echo "setup_bench: could not install python3-siconos: the Siconos comparison will be skipped"
fi
exit 0
