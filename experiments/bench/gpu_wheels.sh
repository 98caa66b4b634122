#!/usr/bin/env bash
# The wheels the GPU machine lacks (it has JAX with CUDA, flax, optax, chex, orbax, numpy,
# scipy, etils, absl-py, matplotlib, pillow, imageio, onnx, onnxruntime), for Python 3.12 on
# x86-64, into .whl/ of the repository root (ignored by git). About 29 MB.
#
#   bash experiments/bench/gpu_wheels.sh
#   # then each device call carries .whl and starts with:
#   python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
#     --target /tmp/site .whl/*.whl && export PYTHONPATH=/tmp/site:$PWD || exit
set -euo pipefail
cd "$(dirname "$0")/../.."
exclude=$(git rev-parse --git-path info/exclude)
mkdir -p "$(dirname "$exclude")"
grep -qxF '/.whl/' "$exclude" 2>/dev/null || echo '/.whl/' >> "$exclude"
rm -rf .whl
platforms=()
for p in manylinux_2_28_x86_64 manylinux_2_27_x86_64 manylinux_2_17_x86_64 manylinux2014_x86_64 manylinux1_x86_64; do
  platforms+=(--platform "$p")
done
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  "${platforms[@]}" -d .whl \
  mujoco==4.0.1 mujoco-core==4.0.1 mujoco-studio==4.0.1 mujoco-mjx==3.17.0 glfw pyopengl \
  trimesh tensorboardX
du -sh .whl
