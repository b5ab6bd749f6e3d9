#!/usr/bin/env bash
# Installs everything the project needs to build and test on Debian 12.
# Idempotent: when every package is already present it prints one line and exits.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libembree-dev libopenexr-dev libspdlog-dev libgtest-dev libgmock-dev libbenchmark-dev
  libtbb-dev libxxhash-dev libzstd-dev libassimp-dev libcli11-dev libsqlite3-dev
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  libpng-dev assimp-testmodels nlohmann-json3-dev python3-yaml clang
  libhwy-dev
  libvulkan-dev glslc mesa-vulkan-drivers vulkan-validationlayers
  liberfa-dev libssl-dev openssl strace
  prometheus-cpp-dev libseccomp-dev
)

# kubectl renders the Kubernetes manifests in the tests (`kubectl kustomize`, offline):
# Debian's kubernetes-client, only when no kubectl is there (some machines ship another
# kubectl package, and the two conflict on /usr/bin/kubectl).
if ! command -v kubectl >/dev/null 2>&1; then
  PACKAGES+=(kubernetes-client)
fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages already installed"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "setup: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "setup: done"
