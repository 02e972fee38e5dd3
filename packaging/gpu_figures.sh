#!/usr/bin/env bash
# Issue 19's GPU figures on a machine with a GPU and no network (README, "On a GPU again").
#
#   packaging/gpu_figures.sh pack [DIR]         here, with network: DIR (default .gpu) gets what
#                                               the GPU machine lacks - the wheels for its Python
#                                               (PYVER, default 3.12), Mitsuba cut down to
#                                               scalar_rgb, the references cached here, the data
#   packaging/gpu_figures.sh run [DIR] [OUT]    there, from the repository root: installs DIR
#                                               into /tmp/site and writes every bench's JSON and
#                                               log to OUT (default ./gpu-figures)
#
# `run` takes a few minutes on an H100: bench table3 (the target cells), bench profile with each
# lobe-walk tuning, bench pathtracer-ratio (the full grid against the cached references), bench
# glossy, bench viewer (balanced: an orbit and a roughness change). DIR is about 35 MB; add it
# to .git/info/exclude. PY: the Python that runs the benches (default python3); QUICK=1: every
# bench at a toy size (to check the script anywhere). Nothing here runs in CI.
set -uo pipefail
cd "$(dirname "$0")/.."
verb=${1:-}
DIR=${2:-.gpu}
PYVER=${PYVER:-3.12}
# Mitsuba's plugins the reference protocol (app/bench/mitsuba_scene.py) loads, and a few spare
PLUGINS="area bitmap box diffuse hdrfilm independent merge path perspective principled srgb
         uniform twosided constant ply obj"

pack() {
    local py=.venv/bin/python tmp
    tmp=$(mktemp -d)
    mkdir -p "$DIR/whl" "$DIR/refs" "$DIR/data" || exit 1
    for spec in moderngl==5.13.0 glcontext==3.1.0 OpenEXR==3.5.3 trimesh==4.12.2 \
                DracoPy==1.7.0 mitsuba==3.9.1 drjit==1.5.0; do
        "$py" -m pip download -q --no-deps --only-binary=:all: --python-version "$PYVER" \
            --implementation cp --platform manylinux_2_28_x86_64 \
            --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
            --platform manylinux2014_x86_64 --platform manylinux1_x86_64 -d "$tmp" "$spec" \
            || { echo "pack: cannot download $spec" >&2; exit 1; }
    done
    mv "$tmp"/moderngl-* "$tmp"/glcontext-* "$tmp"/openexr-* "$tmp"/trimesh-* \
       "$tmp"/dracopy-* "$DIR/whl/"
    # Mitsuba: only scalar_rgb and the plugins above (the wheel alone is 63 MB, 14 MB so)
    (cd "$tmp" && unzip -q mitsuba-*.whl && unzip -q drjit-*.whl && rm -f ./*.whl \
        && rm -rf drjit/include share mitsuba/include mitsuba/cmake mitsuba/mitsuba_stubs \
                  mitsuba/pkgconfig mitsuba/*.pyi mitsuba/llvm_* mitsuba/cuda_* \
                  mitsuba/scalar_spectral* mitsuba/scalar_mono* mitsuba/scalar_rgb_polarized* \
                  mitsuba/data/srgb.coeff mitsuba/data/sunsky mitsuba/python/test \
        && for f in mitsuba/plugins/*.so; do
               case " $(echo $PLUGINS) " in *" $(basename "$f" .so) "*) ;; *) rm "$f" ;; esac
           done \
        && tar -cJf mitsuba.tar.xz drjit drjit-*.dist-info mitsuba mitsuba-*.dist-info) \
        || { echo "pack: cannot cut Mitsuba down" >&2; exit 1; }
    mv "$tmp/mitsuba.tar.xz" "$DIR/"
    rm -rf "$tmp"
    local cache=${SCANLIGHT_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/scanlight}/tradeoff
    cp "$cache"/*256x256* "$DIR/refs/" 2>/dev/null \
        || echo "pack: no cached references in $cache: run bench pathtracer-ratio here first"
    cp ../shared/data/apartment.exr ../shared/data/bunny.glb "$DIR/data/" || exit 1
    # glvnd's EGL loader, for a GPU machine whose image lacks libEGL.so.1 (best effort: apt)
    mkdir -p "$DIR/gl" && (cd "$DIR/gl" && apt-get download -q libegl1 libglvnd0 libopengl0 \
        libgl1 libglx0 libgles2 > /dev/null 2>&1) || echo "pack: no glvnd packages (apt)"
    du -sh "$DIR"
}

run() {
    local OUT=${1:-gpu-figures} T0
    T0=$(date +%s)
    stamp() { echo "=== $(( $(date +%s) - T0 )) s: $*"; }
    mkdir -p "$OUT"
    local PY=${PY:-python3}
    if ! ldconfig -p | grep -q libEGL.so.1 && compgen -G "$DIR/gl/*.deb" > /dev/null; then
        for f in "$DIR"/gl/*.deb; do dpkg -x "$f" /; done; ldconfig     # root only
    fi
    $PY -m pip install -q --no-index --no-deps --no-compile --no-cache-dir \
        --target /tmp/site "$DIR"/whl/*.whl && tar -xJf "$DIR/mitsuba.tar.xz" -C /tmp/site \
        || { echo "run: cannot install $DIR" >&2; exit 1; }
    export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 SCANLIGHT_CACHE=/tmp/scanlight-cache
    mkdir -p ../shared/data "$SCANLIGHT_CACHE/tradeoff" || exit 1
    for f in "$DIR"/data/*; do                      # ../shared/data may be read-only
        [ -e "../shared/data/${f##*/}" ] || cp "$f" ../shared/data/ || exit 1
    done
    cp "$DIR"/refs/* "$SCANLIGHT_CACHE/tradeoff/" 2>/dev/null
    $PY -c "import moderngl; c = moderngl.create_standalone_context(backend='egl', \
require=430); print(c.info['GL_RENDERER'], c.info['GL_VERSION'])" | tee "$OUT/renderer.txt"
    local b=($PY -m app bench) vps="128 512" t3=(--viewports 128,512 --microbuffers 16,24)
    local ptr=(--frames 5 --rooms demo,apartment --assets sphere,bunny) gl=() vw=(--presets
        balanced --sliders roughness)
    if [ "${QUICK:-0}" = 1 ]; then
        vps=32; t3=(--viewports 32 --microbuffers 16); ptr=(--quick)
        gl=(--roughness 0.2 --kinds metal --modes classic)
        vw=(--presets preview --sliders '' --size 320x200)
    fi
    "${b[@]}" table3 "${t3[@]}" --views closeup --modes classic,hybrid --repeat 3 \
        --json "$OUT/table3.json" > "$OUT/table3.log" 2>&1
    stamp "table3 $?"
    for vp in $vps; do for t in auto software; do
        local pm=16; [ "$vp" -ge 512 ] && pm=24     # the README tables: 128 / 16, 512 / 24
        "${b[@]}" profile --viewport $vp --microbuffer $pm --modes classic,hybrid \
            --lobe-tuning $t --json "$OUT/profile_${vp}_$t.json" > "$OUT/profile_${vp}_$t.log" 2>&1
        stamp "profile $vp $t $?"
    done; done
    "${b[@]}" pathtracer-ratio "${ptr[@]}" --json "$OUT/ptr.json" > "$OUT/ptr.log" 2>&1
    stamp "pathtracer-ratio $?"
    "${b[@]}" glossy "${gl[@]}" --repeat 3 --json "$OUT/glossy.json" > "$OUT/glossy.log" 2>&1
    stamp "glossy $?"
    "${b[@]}" viewer "${vw[@]}" --timeout 60 --json "$OUT/viewer.json" > "$OUT/viewer.log" 2>&1
    stamp "viewer $?"
}

case "$verb" in
    pack) pack ;;
    run) run "${3:-}" ;;
    *) echo "usage: packaging/gpu_figures.sh pack [DIR] | run [DIR] [OUT]" >&2; exit 2 ;;
esac
