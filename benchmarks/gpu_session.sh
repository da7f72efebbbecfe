#!/usr/bin/env bash
# One measuring session on a CUDA machine: the numbers in docs/archive/performance_notebook.md come from here.
# Usage: bash benchmarks/gpu_session.sh OUTDIR [bench|still|modes|placement|placement-graph|walls|collision|lean|kernel-shape|coarse-density|coarse-correction|coarse-correction-shape|coarse-correction-still|density-kernel|density-kernel-still|coarse-cost|coarse-sweeps|box-runs|waves|wave-starts|coarse-surface|coarse-damping|damping-interval|damping-interval-box|damping-interval-wave|damping-interval-pool|pool-settle|pool-pump|pool-one-kernel|box-one-kernel|box-starts|default-kernel|compression-damping|compression-damping-cost|one-kernel-inverse-h|tolerance-even-stops|subpasses|subpasses-cost|constraint-moves-pool|constraint-moves-cost|constraint-moves-whole|contact-moves-first-cost|contact-moves-first-pool|contact-moves-first-tests|one-iteration-two-passes|odd-count-step|odd-count-pool|worlds|ncu|ncu-kernels|variants|tolerance|tolerance-small|tolerance-chart|tolerance-i2|accuracy|accuracy-causes|exact|exact-i2|chart-default|chart-default-8x4|wave-default-kernel|foam-clamp|jet|surge|diffuse|render|usd|gallery|gltests|tests]...
# tests and usd need usd-core (pxr) beside newton and warp; the rest runs without it
set -u
out=${1:?output folder}; shift
export PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm --format=csv | tee "$out/gpu.txt"
# the GPU's model in the names of the files written (h100, h200, ...; "gpu" if not recognised)
gpu=$(nvidia-smi --query-gpu=name --format=csv,noheader | head -1 | grep -oiE '[a-z]?[0-9]{2,4}[a-z]*' | head -1 | tr 'A-Z' 'a-z')
gpu=${gpu:-gpu}
# an archived patch on or off ($1 on|off, $2 its path). Patches written before a keyword of the solver apply to the
# tree without it: the keywords' own patches (the newest first: fluid_compression_damping, fluid_density_kernel) are
# then taken off until the patch applies, and put back after. A mode may set apply_options (git apply's --exclude,
# which must come before the --include) to put on a part of a patch
keywords="docs/archive/patches/compression_damping_keyword.patch docs/archive/patches/density_kernel_keyword.patch"
apply_options=()
archived_patch() {
  local options=(${apply_options[@]+"${apply_options[@]}"} --include='newton/*')
  if [ "$1" = on ]; then
    : > /tmp/keywords_off
    for k in $keywords; do
      git apply --check "${options[@]}" "$2" 2>/dev/null && break
      git apply -R "$k" && echo "$k" >> /tmp/keywords_off
    done
    git apply "${options[@]}" "$2"
  else
    git apply -R "${options[@]}" "$2"
    tac /tmp/keywords_off 2>/dev/null | while read -r k; do git apply "$k"; done
    rm -f /tmp/keywords_off
  fi
}
# the 100k dam break with a change ($1, a patch) on, taken off and put back, in one session; records tagged $2
dam_break_without() {
  for v in after before after2; do
    [ $v = before ] && git apply -R "$1"
    [ $v = after2 ] && git apply "$1"
    python3 -m benchmarks dam_break --trials 3 --json "$out/dam_break_100k_${2}_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
  done
}
# the still columns with "one_kernel" and the coarse correction (the 100k pool, 24 and 40 layers); records
# rest_column_NxNxL_one_kernel_coarse_correction$1_GPU.json, the rest of the arguments passed to rest_column
corrected_still_columns() {
  local tag=$1; shift
  for size in 50x40 12x24 12x40; do
    n=${size%x*}; l=${size#*x}; echo "== still, $n x $n x $l $*"
    python3 -m benchmarks rest_column --device cuda:0 --n $n --layers $l --density-kernel one_kernel \
      --coarse-correction 0.5 "$@" --json "$out/rest_column_${n}x${n}x${l}_one_kernel_coarse_correction${tag}_${gpu}.json" \
      2>&1 | grep -A1 '^device' | tail -1
  done
}
# every fluid test's CUDA variant (the image tests run under gltests: they need NVIDIA's GL); the output goes to
# $out/cuda_tests_$1.txt as it runs, a line a test, so a run cut by the call's time limit still says which passed
cuda_tests() {
  local log="$out/cuda_tests_$1.txt"
  python3 -m pytest -v -rf -k cuda newton/tests/test_solver_xpbd_fluid.py \
    $(ls newton/tests/test_fluid_*.py | grep -v test_fluid_render_gl.py) > "$log" 2>&1
  tail -25 "$log"
}
# the 100k and 1M dam breaks (the sizes in $1) for each run ("tag kernel [damping]") of the rest of the arguments,
# alternated; runs whose tag matches the pattern $3 have the patch $4 put on ($5 = on: an archived variant, by
# archived_patch) or taken off ($5 = off: main's own change) for them. Records dam_break_SIZE_$2TAG_GPU.json
dam_break_patch_runs() {
  local sizes=$1 prefix=$2 match=$3 patch=$4 direction=$5 size sizeflags run
  shift 5
  # (the runs are kept apart: set -- below replaces the arguments, which the next size would read)
  local runs=("$@")
  local there="git apply -R" back="git apply"
  [ "$direction" = on ] && there="archived_patch on" && back="archived_patch off"
  for size in $sizes; do
    sizeflags=""
    [ "$size" = 1m ] && sizeflags="--particles 1000000 --warmup-frames 20 --frames 10"
    for run in "${runs[@]}"; do
      set -- $run
      case $1 in $match) $there "$patch" ;; esac
      python3 -m benchmarks dam_break --density-kernel "$2" ${3:+--compression-damping $3} $sizeflags --trials 2 \
        --json "$out/dam_break_${size}_${prefix}${1}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
      case $1 in $match) $back "$patch" ;; esac
    done
  done
}
# modes measuring the defaults of today; every other mode was written while poly6 was the default density kernel (to
# 2026-11-30) and runs the tree with that default, so its records repeat: the change that made the one kernel the
# default is taken off for it (docs/archive/patches/one_kernel_default.patch) and put back after
current_modes=" default-kernel chart-default chart-default-8x4 wave-default-kernel foam-clamp gallery tests gltests "
default_patch=docs/archive/patches/one_kernel_default.patch
for what in "$@"; do
  poly6_default=0
  if [[ "$current_modes" != *" $what "* ]]; then
    git apply -R "$default_patch" && poly6_default=1
  fi
  case $what in
    bench)
      python3 -m benchmarks dam_break --kernel-timing --json "$out/dam_break_100k.json" 2>&1 | grep -v '^Module'
      python3 -m benchmarks dam_break --particles 1000000 --warmup-frames 20 --frames 10 --trials 3 \
        --json "$out/dam_break_1m.json" 2>&1 | grep -v '^Module' ;;
    still)
      # still water (docs/archive/validation_notebook.md "Still water") and the cost of the step bound and the non-affine damping
      # (docs/archive/performance_notebook.md "Still water"): the solver's defaults against the keywords before them
      python3 -m benchmarks rest_column --device cuda:0 --json "$out/rest_column_12x12x24_${gpu}.json" 2>&1 | grep -A1 '^device'
      python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --json "$out/rest_column_50x50x40_${gpu}.json" 2>&1 | grep -A1 '^device'
      for v in "" "--relaxation 1 --nonaffine-damping 0" "--viscosity 0" "--viscosity 0 --relaxation 1 --nonaffine-damping 0"; do
        tag=${v//[ -.]/_}; echo "== 100k $v"
        python3 -m benchmarks dam_break $v --trials 3 --json "$out/dam_break_100k_still${tag}_${gpu}.json" 2>&1 | grep -A1 "^device"
      done
      for v in "" "--relaxation 1 --nonaffine-damping 0"; do
        tag=${v//[ -.]/_}; echo "== 1M $v"
        python3 -m benchmarks dam_break $v --particles 1000000 --warmup-frames 20 --frames 10 --trials 3 \
          --json "$out/dam_break_1m_still${tag}_${gpu}.json" 2>&1 | grep -A1 "^device"
      done ;;
    modes)
      # what moves in still water: the 100k pool split by scale and the floating box over time, today's solver and
      # with docs/archive/patches/one_kernel_density.patch (docs/archive/validation_notebook.md "What moves in still water")
      for patch in "" one_kernel_density; do
        [ -n "$patch" ] && archived_patch on "docs/archive/patches/$patch.patch"
        tag=${patch:-today}
        for v in "" "--iterations 4" "--substeps 16"; do
          echo "== pool $tag $v"
          python3 docs/validation/still_modes/pool_modes.py --device cuda:0 --n 50 --layers 40 $v \
            --out "$out/pool_modes_50x50x40_${tag}${v//[ -]/_}_${gpu}.json" 2>&1 | grep -E '^ *[0-9.]+ s' | tail -1
        done
        python3 docs/validation/floating_box/series.py cuda:0 10 > "$out/floating_box_series_${tag}_${gpu}.txt" 2>/dev/null
        tail -2 "$out/floating_box_series_${tag}_${gpu}.txt"
        [ -n "$patch" ] && archived_patch off "docs/archive/patches/$patch.patch"
      done ;;
    placement)
      # over-packed placements moved apart before they move (docs/archive/validation_notebook.md "Over-packed starts"):
      # the packed start at three packings and at 100k (the first frame's time holds the relaxation; at 1.0 with
      # --check-placement, the check where nothing is packed), the cost where nothing was placed (the 100k dam break
      # with the commit that added it and without), and the CUDA tests
      for f in 0.5 0.7 0.9; do
        python3 -m benchmarks packed_start --device cuda:0 --fraction $f --json "$out/packed_start_${f}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
      done
      for f in 0.5 0.7 1.0; do
        check=""; [ $f = 1.0 ] && check="--check-placement"
        python3 -m benchmarks packed_start --device cuda:0 --block 50 --layers 40 --height 8 --seconds 0.5 --fraction $f \
          $check --json "$out/packed_start_100k_${f}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
      done
      # (the change that added it, from git; PLACEMENT_PATCH names the patch file where the copy has no history)
      if [ -n "${PLACEMENT_PATCH:-}" ]; then cp "$PLACEMENT_PATCH" /tmp/placement.patch; else
        placement=$(git log --diff-filter=A --format=%h -1 -- newton/_src/solvers/xpbd/fluid/placement.py)
        git diff "$placement~1" "$placement" -- newton/_src > /tmp/placement.patch
      fi
      for round in 1 2; do
        for tag in without with; do
          [ $tag = without ] && git apply -R /tmp/placement.patch
          echo "== 100k dam break $tag placement check, round $round"
          python3 -m benchmarks dam_break --trials 3 --json "$out/dam_break_100k_${tag}_placement_${round}_${gpu}.json" 2>&1 | grep -A1 "^device"
          [ $tag = without ] && git apply /tmp/placement.patch
        done
      done
      python3 -m pytest -q -k cuda newton/tests/test_fluid_placement.py newton/tests/test_fluid_stress.py \
        newton/tests/test_fluid_reset.py 2>&1 | tail -5 ;;
    placement-graph)
      # the relaxation's rounds as a conditional loop in a CUDA graph (docs/archive/validation_notebook.md "Over-packed
      # starts"): the 40-layer 100k block in a graph and eager, the check where nothing is packed in a graph and eager,
      # and the CUDA tests
      ps="python3 -m benchmarks packed_start --device cuda:0"
      for f in 0.5 0.7; do
        $ps --block 50 --layers 40 --height 8 --seconds 0.5 --fraction $f --graph \
          --json "$out/packed_start_100k_${f}_graph_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
      done
      for f in 0.5 0.7; do
        $ps --block 50 --layers 40 --height 8 --seconds 0.5 --fraction $f \
          --json "$out/packed_start_100k_${f}_eager_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
      done
      $ps --fraction 0.7 --graph --json "$out/packed_start_0.7_graph_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
      for mode in "" "--graph"; do
        tag=${mode:-eager}; tag=${tag#--}
        $ps --block 50 --layers 40 --height 8 --seconds 0.5 --fraction 1 --check-placement $mode \
          --json "$out/packed_start_100k_1.0_check_${tag}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
      done
      python3 -m pytest -q -k cuda newton/tests/test_fluid_placement.py newton/tests/test_fluid_reset.py \
        newton/tests/test_fluid_stress.py newton/tests/test_solver_xpbd_fluid.py 2>&1 | tail -5 ;;
    walls)
      # the walls' density by a box's edges and corners and in a tank's corner (docs/validation.rst "Where the method
      # fails"), the CUDA tests of the walls, and the 100k dam break with a change to the walls taken off and put
      # back (WALLS_PATCH; the solid walls not adopted: archived_patch on docs/archive/patches/solid_walls.patch first)
      python3 docs/validation/walls/edge_density.py --device cuda:0 --json "$out/edge_density_${gpu}.json" 2>&1 | grep particles
      python3 -m pytest -q -k "cuda and (wall or edge or rest_lattice or archimedes or floats)" \
        newton/tests/test_solver_xpbd_fluid.py 2>&1 | tail -2
      [ -n "${WALLS_PATCH:-}" ] && dam_break_without "$WALLS_PATCH" walls ;;
    collision)
      # the cost of continuous collision at the 100k dam break (docs/archive/performance_notebook.md "Continuous collision")
      for v in "" "--no-continuous-collision"; do
        tag=${v//[ -.]/_}; echo "== 100k $v"
        python3 -m benchmarks dam_break $v --trials 5 --json "$out/dam_break_100k_collision${tag}_${gpu}.json" 2>&1 | grep -A2 "^device"
      done
      # a heightfield floor for the ground plane (docs/performance/collision/), with and without the guard
      for v in "" "--no-continuous-collision"; do
        tag=${v//[ -.]/_}; echo "== 100k terrain $v"
        python3 -m benchmarks dam_break --terrain-bump 0.5 $v --trials 3 \
          --json "$out/dam_break_100k_terrain${tag}_${gpu}.json" 2>&1 | grep -A2 "^device"
      done
      # a change to the guard taken off and put back between runs: COLLISION_PATCH names its patch
      # (the barrel-sided cylinders: git diff 4328822 41e52ea -- newton/_src > barrel.patch)
      [ -n "${COLLISION_PATCH:-}" ] && dam_break_without "$COLLISION_PATCH" change
      python3 -m pytest -q -k cuda newton/tests/test_fluid_continuous_collision.py newton/tests/test_fluid_placement.py \
        newton/tests/test_fluid_diffuse.py 2>&1 | tail -5 ;;
    lean)
      # the floating box's lean against the curvature of the sum the solver holds (docs/validation.rst "Floating
      # box", archive "The lean and the constraint's shear curvature"): twelve starts 1 um apart with today's
      # solver, then with docs/archive/patches/one_kernel_density.patch at 1.8 and 2.0 spacings
      r=docs/validation/floating_box/repeat_runs.py
      python3 $r --device cuda:0 --runs 12 --offset 1e-6 --json "$out/repeat_offsets_today_${gpu}.json" 2>&1 | grep '^damping'
      archived_patch on docs/archive/patches/one_kernel_density.patch
      for h in 1.8 2.0; do
        python3 $r --device cuda:0 --runs 12 --offset 1e-6 --smoothing-ratio $h \
          --json "$out/repeat_offsets_one_kernel_h${h}_${gpu}.json" 2>&1 | grep '^damping'
      done
      archived_patch off docs/archive/patches/one_kernel_density.patch ;;
    kernel-shape)
      # one kernel of the shape (1 - r/h)^2.5 against today's solver (docs/archive/validation_notebook.md, "The kernel's
      # shape"; docs/archive/patches/one_kernel_polynomial.patch, FLUID_KERNEL_EXP), and spiky (exponent 3) for the
      # dam break: the 100k dam break, the still column and the 100k pool (also at 8 x 4), the standing wave 8 across
      # and the floating box's twelve starts
      r=docs/validation/floating_box/repeat_runs.py
      for v in today 2.5 3; do
        if [ $v = 2.5 ]; then archived_patch on docs/archive/patches/one_kernel_polynomial.patch; fi
        [ $v != today ] && export FLUID_KERNEL_EXP=$v
        tag=${v/#[0-9]*/one_kernel_exponent_$v}
        echo "== $tag"
        python3 -m benchmarks dam_break --trials 3 --json "$out/dam_break_100k_${tag}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        [ $v = 3 ] && continue
        python3 -m benchmarks rest_column --device cuda:0 --json "$out/rest_column_12x12x24_${tag}_${gpu}.json" 2>&1 \
          | grep -A1 '^device' | tail -1
        python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 \
          --json "$out/rest_column_50x50x40_${tag}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        if [ $v = 2.5 ]; then
          for l in 24 40; do
            n=12; [ $l = 40 ] && n=50
            python3 -m benchmarks rest_column --device cuda:0 --n $n --layers $l --iterations 4 \
              --json "$out/rest_column_${n}x${n}x${l}_${tag}_8x4_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
          done
        fi
        python3 -m benchmarks sloshing --device cuda:0 --depth-particles 8 \
          --json "$out/sloshing_n20_8_across_${tag}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        python3 $r --device cuda:0 --runs 12 --offset 1e-6 --json "$out/repeat_offsets_${tag}_${gpu}.json" 2>&1 | grep '^damping'
      done
      unset FLUID_KERNEL_EXP
      archived_patch off docs/archive/patches/one_kernel_polynomial.patch ;;
    coarse-density)
      # the coarse density correction in Warp kernels (docs/archive/scratch/coarse_density_warp.py; docs/archive/
      # validation_notebook.md, "A coarse density correction against the ring") on the shape (1 - r/h)^2.5
      # (one_kernel_polynomial.patch): its cost per captured frame at 100k and 1M (cells of 3 and 5 spacings, 2 to 8
      # sweeps), the 100k pool and the 24- and 40-layer columns with it
      s=docs/archive/scratch/coarse_density_warp.py
      archived_patch on docs/archive/patches/one_kernel_polynomial.patch
      export FLUID_KERNEL_EXP=2.5
      for c in 3:2 3:4 3:8 5:4; do
        COARSE_CELL=${c%:*} COARSE_SWEEPS=${c#*:} python3 $s --time 50 40 cuda:0 200 2>&1 | grep particles
      done
      for c in 3 5; do COARSE_CELL=$c python3 $s --time 100 100 cuda:0 30 2>&1 | grep particles; done
      # n x n x layers : box [m] : cell [spacings] : sweeps
      for c in 50x40:2.5,2.5,3.0:3:4 50x40:2.5,2.5,3.0:3:8 50x40:2.5,2.5,3.0:5:4 12x24:0.6,0.6,1.8:3:4 \
        12x40:0.6,0.6,3.0:3:4; do
        IFS=: read -r size box cell k <<< "$c"; n=${size%x*}; l=${size#*x}
        COARSE_CELL=$cell COARSE_SWEEPS=$k COARSE_BOX=$box COARSE_D=0.05 python3 $s rest_column --device cuda:0 --n $n \
          --layers $l --json "$out/rest_column_${n}x${n}x${l}_exponent_2.5_coarse_density_warp_cell_${cell}_${k}_sweeps_${gpu}.json" \
          2>&1 | grep -A1 '^device' | tail -1
      done
      unset FLUID_KERNEL_EXP
      archived_patch off docs/archive/patches/one_kernel_polynomial.patch ;;
    coarse-correction|coarse-correction-shape|coarse-correction-still)
      # the solver's coarse density correction (fluid_coarse_correction; docs/validation.rst "Still water"). Today's
      # kernel: its tests on CUDA and the 100k dam break's time per frame and density error without and with it.
      # -shape, on (1 - r/h)^2.5 (one_kernel_polynomial.patch): the 100k and 1M dam breaks without and with it.
      # -still, on that shape: the 100k pool and the 24- and 40-layer columns with it
      tag=""
      if [ $what != coarse-correction ]; then
        archived_patch on docs/archive/patches/one_kernel_polynomial.patch
        export FLUID_KERNEL_EXP=2.5; tag=exponent_2.5_
      else
        python3 -m pytest -q -k cuda newton/tests/test_fluid_coarse_correction.py newton/tests/test_fluid_reset.py 2>&1 | tail -1
      fi
      if [ $what = coarse-correction-still ]; then
        for size in 50x40 12x24 12x40; do
          n=${size%x*}; l=${size#*x}
          python3 -m benchmarks rest_column --device cuda:0 --n $n --layers $l --coarse-correction 0.5 \
            --json "$out/rest_column_${n}x${n}x${l}_${tag}coarse_correction_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        done
      else
        for v in "" "--coarse-correction 0.5"; do
          t=${tag}${v:+coarse_correction_}
          python3 -m benchmarks dam_break $v --trials 3 --json "$out/dam_break_100k_${t}${gpu}.json" 2>&1 \
            | grep -A1 '^device' | tail -1
          [ -n "$tag" ] && python3 -m benchmarks dam_break $v --particles 1000000 --warmup-frames 20 --frames 10 \
            --trials 3 --json "$out/dam_break_1m_${t}${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        done
      fi
      if [ -n "$tag" ]; then
        unset FLUID_KERNEL_EXP
        archived_patch off docs/archive/patches/one_kernel_polynomial.patch
      fi ;;
    density-kernel)
      # fluid_density_kernel (docs/performance.rst, docs/validation.rst "Still water"): the 100k and 1M dam breaks before
      # the keyword existed (docs/archive/patches/density_kernel_keyword.patch taken off), with it at "poly6", with
      # "one_kernel", and with "one_kernel" and the coarse correction
      for v in before poly6 one_kernel one_kernel_coarse_correction; do
        flags=""
        [ $v = one_kernel ] && flags="--density-kernel one_kernel"
        [ $v = one_kernel_coarse_correction ] && flags="--density-kernel one_kernel --coarse-correction 0.5"
        [ $v = before ] && git apply -R docs/archive/patches/compression_damping_keyword.patch \
          && git apply -R docs/archive/patches/density_kernel_keyword.patch
        python3 -m benchmarks dam_break $flags --trials 3 --json "$out/dam_break_100k_kernel_${v}_${gpu}.json" 2>&1 \
          | grep -A1 '^device' | tail -1
        python3 -m benchmarks dam_break $flags --particles 1000000 --warmup-frames 20 --frames 10 --trials 3 \
          --json "$out/dam_break_1m_kernel_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        [ $v = before ] && git apply docs/archive/patches/density_kernel_keyword.patch \
          && git apply docs/archive/patches/compression_damping_keyword.patch
      done ;;
    coarse-cost)
      # the coarse correction's cost (docs/performance.rst): the 100k and 1M dam breaks with "one_kernel" and the
      # correction before its bounds' bins were capped and its spread summed by warp in slot order
      # (docs/archive/patches/coarse_correction_cost.patch taken off), with the bins capped alone (the spread in fluid
      # order: coarse_spread_fluid_order.patch), with the spread in slot order without the warp's sums
      # (coarse_spread_plain_atomics.patch), and as it is; and with "poly6" and "one_kernel" alone, for the ratios
      corrected="--density-kernel one_kernel --coarse-correction 0.5"
      for v in poly6 one_kernel before fluid_order plain_atomics after; do
        flags=$corrected; timing=""; patch=""
        case $v in
          poly6) flags="" ;;
          one_kernel) flags="--density-kernel one_kernel" ;;
          before) git apply -R docs/archive/patches/coarse_correction_cost.patch ;;
          fluid_order | plain_atomics) patch=docs/archive/patches/coarse_spread_$v.patch; git apply $patch ;;
          after) timing="--kernel-timing" ;;
        esac
        python3 -m benchmarks dam_break $flags $timing --trials 3 --json "$out/dam_break_100k_coarse_${v}_${gpu}.json" 2>&1 \
          | grep -A1 '^device' | tail -1
        python3 -m benchmarks dam_break $flags --particles 1000000 --warmup-frames 20 --frames 10 --trials 3 \
          --json "$out/dam_break_1m_coarse_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        [ $v = before ] && git apply docs/archive/patches/coarse_correction_cost.patch
        [ -n "$patch" ] && git apply -R $patch
      done ;;
    coarse-sweeps)
      # the coarse correction's sweeps a launch each, a black cell relaxing its red neighbours itself
      # (docs/archive/patches/coarse_sweeps_a_launch_a_sweep.patch, not adopted), against a launch per colour (main):
      # the 100k and 1M dam breaks with "one_kernel" and the correction, alternated; and the correction's CUDA tests
      python3 -m pytest -q -k cuda newton/tests/test_fluid_coarse_correction.py 2>&1 | tail -1
      corrected="--density-kernel one_kernel --coarse-correction 0.5"
      sweeps=docs/archive/patches/coarse_sweeps_a_launch_a_sweep.patch
      for v in a_launch_a_sweep a_launch_a_colour a_launch_a_sweep_again; do
        [ $v != a_launch_a_colour ] && git apply $sweeps
        python3 -m benchmarks dam_break $corrected --trials 3 --json "$out/dam_break_100k_coarse_sweeps_${v}_${gpu}.json" 2>&1 \
          | grep -A1 '^device' | tail -1
        python3 -m benchmarks dam_break $corrected --particles 1000000 --warmup-frames 20 --frames 10 --trials 3 \
          --json "$out/dam_break_1m_coarse_sweeps_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        [ $v != a_launch_a_colour ] && git apply -R $sweeps
      done ;;
    density-kernel-still)
      # its tests and the coarse correction's on CUDA; the 100k pool and the 24- and 40-layer columns with
      # "one_kernel" and the coarse correction
      python3 -m pytest -q -k cuda newton/tests/test_fluid_density_kernel.py newton/tests/test_fluid_coarse_correction.py \
        2>&1 | tail -1
      corrected_still_columns "" ;;
    damping-interval)
      # the non-affine damping once in each 1/120 s against every substep (the "before":
      # docs/archive/patches/nonaffine_damping_every_substep.patch; docs/archive/performance_notebook.md "The damping
      # once in four substeps"), alternated: the 100k dam break with viscosity 0 (the damping alone runs the velocity
      # pass) and at the benchmark scene, the 1M one with viscosity 0, the 100k pool; then the CUDA tests of still water
      p=docs/archive/patches/nonaffine_damping_every_substep.patch
      for v in after before after2; do
        [ $v = before ] && archived_patch on $p
        echo "== $v"
        python3 -m benchmarks dam_break --viscosity 0 --trials 3 \
          --json "$out/dam_break_100k_viscosity_0_damping_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        python3 -m benchmarks dam_break --trials 3 --json "$out/dam_break_100k_damping_${v}_${gpu}.json" 2>&1 \
          | grep -A1 '^device' | tail -1
        if [ $v != after2 ]; then
          python3 -m benchmarks dam_break --viscosity 0 --particles 1000000 --warmup-frames 20 --frames 10 --trials 3 \
            --json "$out/dam_break_1m_viscosity_0_damping_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
          python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 \
            --json "$out/rest_column_50x50x40_damping_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        fi
        [ $v = before ] && archived_patch off $p
      done
      python3 -m pytest -q -k cuda newton/tests/test_fluid_still_water.py 2>&1 | tail -3 ;;
    damping-interval-box)
      # the floating box's twelve starts 1 um apart with the damping once in each 1/120 s and every substep
      p=docs/archive/patches/nonaffine_damping_every_substep.patch
      for v in after before; do
        [ $v = before ] && archived_patch on $p
        python3 docs/validation/floating_box/repeat_runs.py --device cuda:0 --runs 12 --offset 1e-6 \
          --json "$out/floating_box_offsets_damping_${v}_${gpu}.json" 2>&1 | grep '^damping'
        [ $v = before ] && archived_patch off $p
      done ;;
    damping-interval-wave)
      # the standing wave with the damping once in each 1/120 s and every substep (the archived patch), at the
      # defaults: 20 per L over 64 starts (the scatter from start to start against the change) and 160 per L, the
      # period read from the crossings and from the extremes (docs/validation.rst, "Still water and floating bodies")
      p=docs/archive/patches/nonaffine_damping_every_substep.patch
      for v in after before; do
        [ $v = before ] && archived_patch on $p
        echo "== $v"
        python3 -m benchmarks sloshing --device cuda:0 --per-length 20 --depth-particles 8 --starts 64 \
          --json "$out/sloshing_starts_n20_damping_${v}_${gpu}.json" 2>&1 | grep -A2 '^device' | tail -2
        python3 -m benchmarks sloshing --device cuda:0 --per-length 160 --depth-particles 8 \
          --json "$out/sloshing_n160_damping_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        [ $v = before ] && archived_patch off $p
      done ;;
    damping-interval-pool)
      # the 100k pool (50 x 50 x 40) with the damping once in each 1/120 s and every substep, alternated, from
      # three starts: a GPU repeats a run bitwise (three runs of one start read the same on 2026-11-29), so the
      # spread is read over starts moved by a micrometre (--offset)
      p=docs/archive/patches/nonaffine_damping_every_substep.patch
      for offset in 0 0.00002 0.00004; do
        for v in after before; do
          [ $v = before ] && archived_patch on $p
          echo "== $v, offset $offset spacings"
          python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --offset $offset \
            --json "$out/rest_column_50x50x40_damping_${v}_offset_${offset}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
          [ $v = before ] && archived_patch off $p
        done
      done ;;
    pool-settle)
      # the 100k pool measured later than issue #23's window, 3 s from each settling time: it does not come to rest
      # (docs/validation.rst, "The deep pool's pump")
      # (one run measured over each window; the records of 2026-11-29 are a run each, the same numbers)
      python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --settle 2 7 17 27 57 \
        --json "$out/rest_column_50x50x40_settle_windows_${gpu}.json" 2>&1 | grep -A5 '^device' ;;
    pool-pump)
      # what keeps the pool moving: width and depth at 17 s, more passes, the warm start, the coarse correction
      # (poly6) from 2 s to 27 s, and the correction's cost on the dam breaks (docs/validation.rst, "The deep pool's pump")
      still() {
        local tag=$1; shift; echo "== $tag"
        python3 -m benchmarks rest_column --device cuda:0 "$@" --json "$out/rest_column_${tag}_${gpu}.json" 2>&1 \
          | grep -A1 '^device' | tail -1
      }
      for size in 12x40 24x40 50x24 50x12; do
        n=${size%x*}; l=${size#*x}; still ${n}x${n}x${l}_settle_17 --n $n --layers $l --settle 17
      done
      still 24x24x40_settle_37 --n 24 --layers 40 --settle 37
      still 24x24x40_i4_settle_17 --n 24 --layers 40 --iterations 4 --settle 17
      still 24x24x40_coarse_correction_0.5_settle_17 --n 24 --layers 40 --coarse-correction 0.5 --settle 17
      # (0.9, recorded on 2026-11-29, is refused since: fluid_warm_start stops at 0.5)
      still 50x50x40_warm_start_0.5_settle_17 --n 50 --layers 40 --warm-start 0.5 --settle 17
      python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --coarse-correction 0.5 --settle 2 7 12 27 \
        --json "$out/rest_column_50x50x40_coarse_correction_0.5_settle_windows_${gpu}.json" 2>&1 | grep -A4 '^device'
      for v in "" "--coarse-correction 0.5"; do
        tag=${v//[ -]/_}; echo "== dam break $v"
        python3 -m benchmarks dam_break $v --trials 3 --json "$out/dam_break_100k_poly6${tag}_${gpu}.json" 2>&1 \
          | grep -A1 '^device' | tail -1
        python3 -m benchmarks dam_break $v --particles 1000000 --warmup-frames 20 --frames 10 --trials 2 \
          --json "$out/dam_break_1m_poly6${tag}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
      done ;;
    pool-one-kernel)
      # the 100k pool and the 24 x 24 x 40 fluid with one kernel for the density and its gradient, measured late as
      # pool-settle measures the defaults: the pump gone, what rests (docs/validation.rst, "The deep pool's pump")
      python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --density-kernel one_kernel --settle 2 7 17 27 \
        --json "$out/rest_column_50x50x40_one_kernel_settle_windows_${gpu}.json" 2>&1 | grep -A5 '^device'
      python3 -m benchmarks rest_column --device cuda:0 --n 24 --layers 40 --density-kernel one_kernel --settle 7 17 \
        --json "$out/rest_column_24x24x40_one_kernel_settle_7_17_${gpu}.json" 2>&1 | grep -A3 '^device' ;;
    box-runs)
      # the floating box of test_floating_box_comes_to_rest repeated at two non-affine dampings (its outcome on a GPU
      # changes from run to run; docs/validation.rst "Floating box"), and the 100k pool and dam break at each
      python3 docs/validation/floating_box/repeat_runs.py --device cuda:0 --runs 6 --damping 0.05 0.1 \
        --json "$out/floating_box_repeat_${gpu}.json" 2>&1 | grep '^damping'
      # and at the default, twelve starts 1 um apart (the CPU's 30 starts: repeat_runs.py --device cpu --runs 30 --offset 1e-6)
      python3 docs/validation/floating_box/repeat_runs.py --device cuda:0 --runs 12 --offset 1e-6 \
        --json "$out/floating_box_offsets_${gpu}.json" 2>&1 | grep '^damping'
      for v in 0.05 0.1; do
        python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --nonaffine-damping $v \
          --json "$out/rest_column_50x50x40_damping_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        python3 -m benchmarks dam_break --nonaffine-damping $v --trials 3 \
          --json "$out/dam_break_100k_damping_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
      done ;;
    box-one-kernel)
      # the floating box's twelve starts 1 um apart with one kernel for the density and its gradient, and at the
      # default kernel, in one session (docs/validation.rst, "Floating box")
      for k in one_kernel poly6; do
        python3 docs/validation/floating_box/repeat_runs.py --device cuda:0 --runs 12 --offset 1e-6 --density-kernel $k \
          --json "$out/floating_box_offsets_${k}_${gpu}.json" 2>&1 | grep '^damping'
      done ;;
    box-starts)
      # the floating box's twelve starts 1 mm apart (0 to 11 mm off centre: independent draws, where starts 1 um apart
      # all sample the centred box), at the defaults and with the one kernel and the compression damping
      # (docs/validation.rst, "Floating box")
      python3 docs/validation/floating_box/repeat_runs.py --device cuda:0 --runs 12 --offset 1e-3 \
        --json "$out/floating_box_offsets_1mm_poly6_${gpu}.json" 2>&1 | grep 'bounds met'
      python3 docs/validation/floating_box/repeat_runs.py --device cuda:0 --runs 12 --offset 1e-3 --density-kernel one_kernel \
        --compression-damping 0.4 --json "$out/floating_box_offsets_1mm_one_kernel_damping_0.4_${gpu}.json" 2>&1 \
        | grep 'bounds met' ;;
    default-kernel)
      # the one kernel as the default (since 2026-11-30): the 100k and 1M dam breaks at the defaults and with "poly6",
      # alternated, one session (docs/performance.rst, "Today's numbers"); the 100k pool over its windows and the
      # floating box's twelve starts 1 mm apart at the defaults (docs/validation.rst, "Still water and floating bodies")
      for size in 100k 1m; do
        sizeflags=""
        [ $size = 1m ] && sizeflags="--particles 1000000 --warmup-frames 20 --frames 10"
        for run in default poly6 default_again; do
          flags=""
          [ $run = poly6 ] && flags="--density-kernel poly6"
          python3 -m benchmarks dam_break $flags $sizeflags --trials 3 \
            --json "$out/dam_break_${size}_${run}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        done
      done
      python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --settle 2 7 17 27 \
        --json "$out/rest_column_50x50x40_defaults_settle_windows_${gpu}.json" 2>&1 | grep -A5 '^device'
      python3 docs/validation/floating_box/repeat_runs.py --device cuda:0 --runs 12 --offset 1e-3 \
        --json "$out/floating_box_offsets_1mm_defaults_${gpu}.json" 2>&1 | grep 'bounds met'
      # and the batched pouring worlds of docs/performance.rst's table (the examples' settings: the defaults)
      python3 -W ignore -m benchmarks batched_worlds --scene pouring --worlds 1024 4096 --per-world 1000 --frames 30 \
        --warmup 5 --task-frames 220 --json "$out/batched_pouring_1000_default_kernel_${gpu}.json" 2>&1 \
        | grep -v '^Module' ;;
    compression-damping)
      # fluid_compression_damping (docs/formulation.rst, "Compression damping"): its cost on the 100k dam break with
      # each kernel, alternated; the one kernel's 100k pool and floating box with it at 0.4
      # (each run: its record's tag, the kernel, the damping if any)
      for run in "one_kernel one_kernel" "one_kernel_0.4 one_kernel 0.4" "poly6 poly6" "poly6_0.4 poly6 0.4" \
        "one_kernel_2 one_kernel"; do
        set -- $run
        flags="--density-kernel $2${3:+ --compression-damping $3}"
        python3 -m benchmarks dam_break $flags --trials 2 --json "$out/dam_break_100k_compression_damping_${1}_${gpu}.json" \
          2>&1 | grep -A1 '^device' | tail -1
      done
      python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --density-kernel one_kernel \
        --compression-damping 0.4 --settle 2 7 --json "$out/rest_column_50x50x40_one_kernel_compression_damping_0.4_${gpu}.json" \
        2>&1 | grep -A3 '^device'
      python3 docs/validation/floating_box/repeat_runs.py --device cuda:0 --runs 12 --offset 1e-6 --density-kernel one_kernel \
        --compression-damping 0.4 --json "$out/floating_box_offsets_one_kernel_compression_damping_0.4_${gpu}.json" 2>&1 \
        | grep '^damping' ;;
    compression-damping-cost)
      # fluid_compression_damping's cost (docs/performance.rst) on the 100k and 1M dam breaks with each kernel,
      # alternated: off; on with its rate read in a second neighbour loop through the particle index
      # (docs/archive/patches/compression_damping_fused_read.patch taken off); on as it is (the rate in the density's
      # own loop, the moves gathered in slot order by the sort). A call brings few files back: the records go in one
      # archive. DAMPING_COST_SIZES="100k" (or "1m") runs one size (a cold machine compiles for minutes)
      dam_break_patch_runs "${DAMPING_COST_SIZES:-100k 1m}" compression_damping_ '*two_loops' \
        docs/archive/patches/compression_damping_fused_read.patch off "one_kernel one_kernel" \
        "one_kernel_0.4_two_loops one_kernel 0.4" "one_kernel_0.4 one_kernel 0.4" "poly6 poly6" \
        "poly6_0.4_two_loops poly6 0.4" "poly6_0.4 poly6 0.4"
      (cd "$out" && tar czf "compression_damping_cost_${DAMPING_COST_SIZES:-all}_${gpu}.tgz" \
        dam_break_*_compression_damping_*_${gpu}.json && rm dam_break_*_compression_damping_*_${gpu}.json) ;;
    one-kernel-inverse-h)
      # the one kernel's q = 1 - |r|/h from a product with 1/h instead of a division per pair
      # (docs/archive/patches/one_kernel_inverse_h.patch put on; docs/archive/performance_notebook.md, "The one kernel's
      # division by h"): the 100k and 1M dam breaks with "one_kernel", alternated with main's division, alone and with
      # the compression damping 0.4; "poly6", which it leaves as it was, for the ratio. The records go in one archive.
      # INVERSE_H_SIZES="100k" (or "1m") runs one size
      dam_break_patch_runs "${INVERSE_H_SIZES:-100k 1m}" "" '*inverse_h*' docs/archive/patches/one_kernel_inverse_h.patch \
        on "poly6 poly6" "one_kernel_inverse_h one_kernel" "one_kernel one_kernel" "one_kernel_0.4_inverse_h one_kernel 0.4" \
        "one_kernel_0.4 one_kernel 0.4" "one_kernel_inverse_h_again one_kernel"
      (cd "$out" && files=$(ls dam_break_*_{poly6,one_kernel*}_${gpu}.json) \
        && tar czf "one_kernel_inverse_h_${INVERSE_H_SIZES:-all}_${gpu}.tgz" $files && rm $files) ;;
    tolerance-even-stops)
      # a tolerance on the XPBD iterations that stops only after an even count (docs/validation.rst, "A tolerance on
      # the XPBD iterations"): the 100k pool with it at 0.005, before it (docs/archive/patches/tolerance_even_stops.patch
      # taken off: a count may stop after one pass, every pass at 0.48), and at the defaults, one session
      for v in density_tolerance_0.005_even_stops density_tolerance_0.005_before_even_stops defaults; do
        flags="--density-tolerance 0.005"; [ $v = defaults ] && flags=""
        case $v in *before*) git apply -R docs/archive/patches/tolerance_even_stops.patch ;; esac
        python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 $flags --settle 2 7 \
          --json "$out/rest_column_50x50x40_${v}_settle_2_7_${gpu}.json" 2>&1 | grep -A3 '^device'
        case $v in *before*) git apply docs/archive/patches/tolerance_even_stops.patch ;; esac
      done ;;
    subpasses)
      # sub-passes that go on from the contacts' correction and stop after an even count (docs/validation.rst,
      # "Sub-passes"), and before them (docs/archive/patches/subpasses_see_contacts.patch taken off), one session:
      # the 100k pool in one XPBD iteration of two passes, the 99,200 Koshizuka & Oka column with a tolerance in
      # one and two iterations of up to four, and the 100k dam break's frame with them
      sa="python3 -W ignore -m benchmarks speed_accuracy --per-l 40 --depth 31 --sample-every 6 --substeps 8"
      for v in after before; do
        [ $v = before ] && git apply -R docs/archive/patches/subpasses_see_contacts.patch
        python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --iterations 1 --max-iterations 2 \
          --settle 2 7 --json "$out/rest_column_50x50x40_iterations_1_max_iterations_2_${v}_settle_2_7_${gpu}.json" \
          2>&1 | grep -A3 '^device'
        for i in 1 2; do
          $sa --iterations --tolerance-iterations $i --max-iterations 4 --tolerances 0.005 \
            --json "$out/speed_accuracy_100k_subpasses_i${i}_tolerance_0.005_${v}_${gpu}.json" 2>&1 | grep -A1 '^mode'
          python3 -m benchmarks dam_break --iterations $i --max-iterations 4 --density-tolerance 0.005 --trials 3 \
            --json "$out/dam_break_100k_subpasses_i${i}_tolerance_0.005_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        done
        [ $v = before ] && git apply docs/archive/patches/subpasses_see_contacts.patch
      done ;;
    subpasses-cost)
      # the defaults' 100k and 1M dam breaks with the sub-passes' change on, taken off and put back (the correction
      # kernel every schedule runs holds the sub-passes' branch; the defaults' physics is bitwise unchanged)
      dam_break_patch_runs "100k 1m" subpasses_ '*before*' docs/archive/patches/subpasses_see_contacts.patch off \
        "after poly6" "before poly6" "after2 poly6" ;;
    constraint-moves-pool|constraint-moves-cost|constraint-moves-whole)
      # the density passes starting from the moves of the constraints solved before them in the XPBD iteration (the
      # walls' contacts; archived, not adopted: docs/archive/validation_notebook.md, "The floor's pump") as measured:
      # docs/archive/patches/density_sees_constraint_moves.patch without its schedule.py part, so on CUDA the second
      # iteration's pass is still evaluated ahead, beside the contacts it then does not see ("ahead"), against main
      # ("before"). constraint-moves-pool: the 100k pool at the defaults over 2-5, 7-10 and 17-20 s;
      # constraint-moves-cost: the defaults' 100k and 1M dam breaks with it on, off and on again;
      # constraint-moves-whole: the whole patch ("whole": no pass ahead where the moves are read), its dam breaks as
      # constraint-moves-cost's, then its 100k pool over 2-5 and 7-10 s
      patch=docs/archive/patches/density_sees_constraint_moves.patch
      apply_options=(--exclude='*/schedule.py')
      case $what in
        constraint-moves-pool)
          for v in ahead before; do
            [ $v = ahead ] && archived_patch on "$patch"
            python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --settle 2 7 17 \
              --json "$out/rest_column_50x50x40_constraint_moves_${v}_settle_2_7_17_${gpu}.json" 2>&1 | grep -A4 '^device'
            [ $v = ahead ] && archived_patch off "$patch"
          done ;;
        constraint-moves-cost)
          dam_break_patch_runs "100k 1m" constraint_moves_ 'ahead*' "$patch" on "ahead poly6" "before poly6" \
            "ahead2 poly6" ;;
        constraint-moves-whole)
          apply_options=()
          dam_break_patch_runs "100k 1m" constraint_moves_ 'whole*' "$patch" on "whole poly6" \
            "before_whole_session poly6" "whole2 poly6"
          archived_patch on "$patch"
          python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --settle 2 7 \
            --json "$out/rest_column_50x50x40_constraint_moves_whole_settle_2_7_${gpu}.json" 2>&1 | grep -A3 '^device'
          archived_patch off "$patch" ;;
      esac
      apply_options=() ;;
    contact-moves-first-cost|contact-moves-first-pool|contact-moves-first-tests)
      # the substep's first density pass alone starting from the contacts' moves (docs/archive/patches/
      # contact_moves_first_iteration.patch; docs/archive/validation_notebook.md, "The floor's pump"): the later
      # passes still run beside upstream's contacts. -cost: the defaults' 100k and 1M dam breaks with it on, off and
      # on again; -pool: the 100k pool over 2-5, 7-10 and 17-20 s with it; -tests: every fluid test's CUDA variant
      # with it
      patch=docs/archive/patches/contact_moves_first_iteration.patch
      case $what in
        contact-moves-first-cost)
          dam_break_patch_runs "100k 1m" contact_moves_ 'first*' "$patch" on "first poly6" \
            "before_first_session poly6" "first2 poly6" ;;
        contact-moves-first-pool)
          archived_patch on "$patch"
          python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --settle 2 7 17 \
            --json "$out/rest_column_50x50x40_contact_moves_first_settle_2_7_17_${gpu}.json" 2>&1 | grep -A4 '^device'
          archived_patch off "$patch" ;;
        contact-moves-first-tests)
          archived_patch on "$patch"
          cuda_tests contact_moves_first
          archived_patch off "$patch" ;;
      esac ;;
    one-iteration-two-passes)
      # one XPBD iteration of two density passes (sub-passes) against the defaults' two iterations of one pass: the
      # same passes, a contact solve and an application of the deltas fewer a substep (docs/archive/
      # performance_notebook.md, "One XPBD iteration of two density passes")
      for run in "100k i2" "100k i1_m2" "100k i2_again" "100k i1_m2_again" "1m i2" "1m i1_m2"; do
        set -- $run
        flags=""; case $2 in i1_m2*) flags="--iterations 1 --max-iterations 2" ;; esac
        [ $1 = 1m ] && flags="$flags --particles 1000000 --warmup-frames 20 --frames 10"
        python3 -m benchmarks dam_break $flags --trials 2 --json "$out/dam_break_${1}_${2}_${gpu}.json" 2>&1 \
          | grep -A1 '^device' | tail -1
      done ;;
    odd-count-step|odd-count-pool)
      # odd fixed pass counts, whose last pass takes half the default step (docs/validation.rst, "Odd pass counts"),
      # against every pass at the step they took before (the linear bound at -1/3, given as fluid_relaxation, so no
      # pass closes). odd-count-step: the 100k dam break at 8 x 1 and 8 x 3, and at the defaults (8 x 2, the physics
      # bitwise unchanged); odd-count-pool: the 100k pool at 8 x 3. The records go in one archive per mode (a call
      # brings few files back)
      [ $what = odd-count-step ] && python3 -m benchmarks dam_break --trials 3 --json "$out/dam_break_100k_i2_${gpu}.json" \
        2>&1 | grep -A1 '^device' | tail -1
      for n in 1 3; do
        [ $what = odd-count-pool ] && [ $n = 1 ] && continue
        before=$(python3 -c "from newton._src.solvers.xpbd.fluid.calibration import stable_relaxation as s; print(repr(s(1.0, 1.8, $n, $n + 1)))")
        for v in closing before; do
          step=""; [ $v = before ] && step="--relaxation $before"
          if [ $what = odd-count-step ]; then
            python3 -m benchmarks dam_break --iterations $n $step --trials 2 \
              --json "$out/dam_break_100k_i${n}_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
          else
            python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 --iterations 3 $step --settle 2 7 \
              --json "$out/rest_column_50x50x40_i3_${v}_${gpu}.json" 2>&1 | grep -A3 '^device'
          fi
        done
      done
      (cd "$out" && files=$(ls dam_break_100k_i*_${gpu}.json rest_column_50x50x40_i3_*_${gpu}.json 2>/dev/null || true) \
        && tar czf "${what//-/_}_${gpu}.tgz" $files && rm $files) ;;
    ncu)
      ncu --kernel-name regex:'build_fluid|compute_fluid_density|apply_fluid_density|apply_fluid_visc' \
        --launch-skip 40 --launch-count 4 --section SpeedOfLight --section Occupancy --section LaunchStats \
        --section MemoryWorkloadAnalysis python3 -m benchmarks dam_break --warmup-frames 2 --frames 1 --trials 1 \
        > "$out/ncu.txt" 2>&1; grep -E 'fluid|Duration|Throughput|Achieved Occupancy|Registers Per|L1/TEX Hit|L2 Hit' "$out/ncu.txt" | head -80 ;;
    ncu-kernels)
      # the density passes' kernels of each density kernel under Nsight Compute: duration, registers, occupancy, and
      # where the time goes (docs/archive/performance_notebook.md, "The one kernel's cost is its neighbours")
      for k in poly6 one_kernel; do
        ncu --kernel-name regex:'compute_fluid_density|apply_fluid_density' --launch-skip 40 --launch-count 4 \
          --section SpeedOfLight --section Occupancy --section LaunchStats --section ComputeWorkloadAnalysis \
          --section WarpStateStats python3 -m benchmarks dam_break --density-kernel $k --warmup-frames 2 --frames 1 \
          --trials 1 > "$out/ncu_$k.txt" 2>&1
        grep -E '^  [a-z_]+.*\(|Duration|Registers Per|Achieved Occupancy|Theoretical Occupancy|Compute \(SM\) Throughput|Memory Throughput|Issue Slots Busy|Warp Cycles Per Issued|Executed Ipc A' \
          "$out/ncu_$k.txt" | head -60
      done ;;
    variants)
      for v in "--iterations 4" "--substeps 4 --iterations 4" "--cohesion 0" "--speed-clamp 0"; do
        echo "== $v"; python3 -m benchmarks dam_break $v --trials 3 --json "$out/dam_break_100k_${v//[ -]/_}.json" 2>&1 | grep -A1 "^device"
      done ;;
    tolerance)
      for v in "--max-iterations 2" "--max-iterations 4 --density-tolerance 0.005" \
               "--iterations 1 --max-iterations 4 --density-tolerance 0.005" "--iterations 1 --max-iterations 2"; do
        echo "== $v"; python3 -m benchmarks dam_break $v --trials 3 --json "$out/dam_break_100k_${v//[ -.]/_}.json" 2>&1 | grep -A1 "^device"
      done ;;
    tolerance-small)
      # the tolerance on a small splash (1,001 particles), against one fixed iteration (docs/archive/validation_notebook.md)
      for t in 0.01 0.002; do
        python3 -m benchmarks dam_break --particles 1000 --trials 3 --iterations 1 --max-iterations 4 \
          --density-tolerance $t --json "$out/dam_break_1k_tolerance_${t}_${gpu}.json" 2>&1 | grep -A1 "^device"
      done
      python3 -m benchmarks dam_break --particles 1000 --trials 3 --iterations 1 \
        --json "$out/dam_break_1k_fixed_1_${gpu}.json" 2>&1 | grep -A1 "^device" ;;
    render)
      # needs an EGL driver (NVIDIA's libEGL_nvidia on a GPU machine) and pyglet on the path
      ls /usr/lib/x86_64-linux-gnu/ | grep -iE '^libEGL' | tee "$out/egl.txt"
      for res in "1920 1080" "1280 720"; do
        read -r w h <<< "$res"
        PYGLET_HEADLESS=1 python3 -m benchmarks render_fluid --width "$w" --height "$h" --png "$out/render_100k_${w}x${h}.png" \
          --json "$out/render_100k_${w}x${h}.json" 2>&1 | grep -v '^Module' | tail -32
      done ;;
    accuracy)
      # the speed-accuracy sweep of docs/archive/validation_notebook.md at 99,200 particles (Koshizuka & Oka column, 40 per L x 31)
      python3 -W ignore -m benchmarks speed_accuracy --per-l 40 --depth 31 --sample-every 6 --tolerances 0.005 0.0025 0.001 \
        --json "$out/speed_accuracy_100k_${gpu}.json" 2>&1 | grep -v '^Module' ;;
    accuracy-causes)
      # what holds the 80-layer column at coarse settings (docs/validation.rst, "Where the method fails"): runs to
      # the end, with the particles the tank walls let through, at the defaults, at the step of 1 without the
      # non-affine damping, and both without continuous collision. Settings the defaults crush (2 x 1, 2 x 2,
      # 4 x 1) are left out: run to the end, their host-side density estimate takes minutes per sample
      for v in "" "--relaxation 1 --nonaffine-damping 0" "--no-continuous-collision" \
        "--relaxation 1 --nonaffine-damping 0 --no-continuous-collision"; do
        tag=${v//[ -.]/_}; echo "== $v"
        for c in "2 8" "4 2" "8 1" "8 2"; do
          read -r s i <<< "$c"
          python3 -W ignore -m benchmarks speed_accuracy --per-l 40 --depth 31 --sample-every 6 --substeps "$s" \
            --iterations "$i" --tolerances --crushed 0 $v \
            --json "$out/speed_accuracy_100k_to_end${tag}_${s}x${i}_${gpu}.json" 2>&1 | tr '\r' '\n' | grep -E '^fixed'
        done
      done ;;
    exact)
      # physical error against cost, problems with exact answers (docs/archive/validation_notebook.md "Exact answers"):
      # the standing wave (about 100k) and Torricelli's jet (about 150k) over substeps x iterations and modes
      python3 -W ignore -m benchmarks accuracy_chart --size large --device cuda:0 --json "$out/accuracy_chart_${gpu}.json" \
        --plot "$out/accuracy_chart_${gpu}.png" 2>&1 | grep -v '^Module' ;;
    exact-i2|chart-default)
      # the same chart at two iterations a substep, every mode, the one kernel with the coarse correction included, in
      # one session (docs/validation.rst, "Exact answers"; EXACT_PROBLEMS picks the problems, a command's time being
      # bounded); plotted with accuracy_chart --from-json. exact-i2 runs with poly6 the default, as it was measured
      # (to 2026-11-30); chart-default at today's defaults (the one kernel), its records tagged default_kernel
      tag=""
      [ "$what" = chart-default ] && tag=default_kernel_
      for problem in ${EXACT_PROBLEMS:-sloshing torricelli pressure}; do
        python3 -W ignore -m benchmarks accuracy_chart --size large --device cuda:0 --iterations 2 --problems "$problem" \
          --json "$out/accuracy_chart_i2_${tag}${problem}_${gpu}.json" 2>&1 | grep -v '^Module'
      done ;;
    chart-default-8x4)
      # the defaults at 8 x 4 beside chart-default (docs/validation.rst, "Which setting for which need")
      python3 -W ignore -m benchmarks accuracy_chart --size large --device cuda:0 --iterations 4 --substeps 8 \
        --modes default --json "$out/accuracy_chart_i4_8_default_kernel_${gpu}.json" 2>&1 | grep -v '^Module' ;;
    wave-default-kernel)
      # the standing wave with the one kernel (the default since 2026-11-30) against poly6 and with the compression
      # damping, over resolutions (starts a hair apart: 64 at 20 per L, 16 at 40, 4 at 80, 1 at 160), 8 x 2; at 160
      # per L also settled 6 s and at 8 x 4 (docs/validation.rst, "Standing wave")
      # WAVE_SIZES picks the resolutions (all four by default), a command's time being bounded
      for n in ${WAVE_SIZES:-20 40 80 160}; do
        starts=$(( n == 20 ? 64 : n == 40 ? 16 : n == 80 ? 4 : 1 ))
        runs=("default|" "poly6|--density-kernel poly6" "compression_damping_0.4|--compression-damping 0.4")
        [ $n = 160 ] && runs+=("settle_6|--settle 6" "8x4|--iterations 4" "poly6_settle_6|--density-kernel poly6 --settle 6")
        for run in "${runs[@]}"; do
          tag=${run%%|*}; flags=${run#*|}; echo "== $n per L, $starts starts, $tag"
          python3 -m benchmarks sloshing --device cuda:0 --per-length $n --depth-particles 8 --starts $starts $flags \
            --json "$out/sloshing_default_kernel_n${n}_${tag}_${gpu}.json" 2>&1 | grep -A2 '^device' | tail -1
        done
      done ;;
    foam-clamp)
      # fluid_xpbd_foam with and without its particle speed clamp (the example's until 2026-11-30), at its test's
      # count and its default one, in the basin as it was (walls 0.6 m, water 0.06 m deep), as tried and as it is
      # (1.5 m, 0.12 m): where spray and water go (docs/archive/validation_notebook.md, "The foam example's clamp");
      # one JSON line a run
      for run in "4000 --clamp --wall-height 0.6 --pool-depth 0.06" "4000 --wall-height 0.6 --pool-depth 0.06" \
        "60000 --clamp --wall-height 0.6 --pool-depth 0.06" "60000 --wall-height 0.6 --pool-depth 0.06" \
        "60000 --wall-height 1.0 --pool-depth 0.06" "60000 --wall-height 1.5 --pool-depth 0.06" \
        "60000 --wall-height 1.0 --pool-depth 0.12" "60000 --wall-height 1.0 --pool-depth 0.2" "4000" "60000"; do
        set -- $run
        python3 -W ignore docs/archive/scratch/foam_clamp.py --device cuda:0 --particle-count $1 --frames 120 "${@:2}" \
          2>&1 | tail -1 | tee -a "$out/foam_clamp_${gpu}.jsonl"
      done ;;
    waves)
      # the standing wave at the smoothing length and damping that keep it, against the defaults, and what the
      # same keywords do to the 100k dam break and the 100k pool (docs/validation.rst, "Standing wave")
      for v in "" "--smoothing-ratio 2.1 --nonaffine-damping 0"; do
        tag=${v:+_waves}; echo "== ${v:-defaults}"
        python3 -m benchmarks dam_break --trials 3 $v --json "$out/dam_break_100k${tag}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        python3 -m benchmarks rest_column --device cuda:0 --n 50 --layers 40 $v \
          --json "$out/rest_column_50x50x40${tag}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        python3 -m benchmarks sloshing --device cuda:0 --depth-particles 8 --control --periods 6 $v \
          --json "$out/sloshing_n20${tag}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        python3 -m benchmarks sloshing --device cuda:0 --per-length 160 --depth-particles 8 $v \
          --json "$out/sloshing_n160${tag}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
      done ;;
    wave-starts)
      # the standing wave as a mean over starts a hair apart, isolated worlds of one model (docs/validation.rst,
      # "Standing wave"): its reading scatters from start to start by more than the 2 % goal
      for n in 20 40; do
        starts=$(( n == 20 ? 64 : 16 ))
        # (with "one_kernel" and the coarse correction: the coarse-surface mode)
        for v in "" "--nonaffine-damping 0 --control --periods 6"; do
          tag=${v:+_nonaffine-damping_0_control}; echo "== $n per L, $starts starts ${v:-defaults}"
          python3 -m benchmarks sloshing --device cuda:0 --per-length $n --depth-particles 8 --starts $starts $v \
            --json "$out/sloshing_starts_n${n}${tag}_${gpu}.json" 2>&1 | grep -A2 '^device' | tail -2
        done
      done ;;
    coarse-surface)
      # the coarse problem's free surface where the fill puts it (main; "after") and at the free-surface cells'
      # centres (docs/archive/patches/coarse_surface_at_cell_centres.patch; "before"), with "one_kernel": the standing
      # wave over starts, the still columns and the dam breaks (docs/validation.rst, "Standing wave");
      # SURFACE_VARIANTS="after before" by default, one of them for a call that would run too long
      corrected="--density-kernel one_kernel --coarse-correction 0.5"
      for v in ${SURFACE_VARIANTS:-after before}; do
        [ $v = before ] && git apply docs/archive/patches/coarse_surface_at_cell_centres.patch
        for n in 20 40; do
          starts=$(( n == 20 ? 64 : 16 ))
          for d in "" "--nonaffine-damping 0 --control --periods 6"; do
            tag=${d:+_d0_control}; echo "== $v: wave, $n per L, $starts starts ${d:-damped}"
            python3 -m benchmarks sloshing --device cuda:0 --per-length $n --depth-particles 8 --starts $starts $corrected $d \
              --json "$out/sloshing_starts_n${n}_one_kernel_coarse_correction${tag}_surface_${v}_${gpu}.json" 2>&1 \
              | grep -A2 '^device' | tail -1
          done
        done
        corrected_still_columns "_surface_$v"
        echo "== $v: dam breaks, 100k and 1M"
        python3 -m benchmarks dam_break --trials 3 $corrected \
          --json "$out/dam_break_100k_coarse_surface_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        python3 -m benchmarks dam_break --particles 1000000 --warmup-frames 20 --frames 10 --trials 3 $corrected \
          --json "$out/dam_break_1m_coarse_surface_${v}_${gpu}.json" 2>&1 | grep -A1 '^device' | tail -1
        [ $v = before ] && git apply -R docs/archive/patches/coarse_surface_at_cell_centres.patch
      done ;;
    coarse-damping)
      # the one kernel with the coarse correction at four non-affine dampings: the standing wave over 64 starts
      # (20 per L) and the still columns (docs/validation.rst, "Standing wave" and "Still column")
      corrected="--density-kernel one_kernel --coarse-correction 0.5"
      for damping in 0 0.02 0.05 0.1; do
        echo "== damping $damping: wave, 20 per L, 64 starts"
        python3 -m benchmarks sloshing --device cuda:0 --depth-particles 8 --starts 64 $corrected \
          --nonaffine-damping $damping --control --periods 6 \
          --json "$out/sloshing_starts_n20_one_kernel_coarse_correction_damping_${damping}_control_${gpu}.json" 2>&1 \
          | grep -A2 '^device' | tail -1
        corrected_still_columns "_damping_$damping" --nonaffine-damping $damping
      done ;;
    jet)
      # Torricelli's jet without the non-affine damping at 32 and 64 substeps, and at eight times the particles
      # (docs/validation.rst, "Exact answers")
      t="python3 -W ignore -m benchmarks torricelli --device cuda:0 --nonaffine-damping 0"
      for cfg in "0.005 16 32 4" "0.005 16 64 2" "0.005 16 64 4" "0.0025 32 32 4" "0.0025 32 64 4"; do
        read -r sp hole sub it <<< "$cfg"
        $t --spacing "$sp" --hole "$hole" --sill "$hole" --substeps "$sub" --iterations "$it" \
          --json "$out/torricelli_${sp}_${sub}x${it}_${gpu}.json" 2>&1 | grep -v '^Module' | tail -2
      done ;;
    tolerance-chart)
      # fixed counts against the tolerance modes at 8 substeps, one session (docs/images/speed_accuracy_tolerance.png)
      sa="python3 -W ignore -m benchmarks speed_accuracy --per-l 40 --depth 31 --sample-every 6 --substeps 8"
      $sa --iterations 1 2 3 4 6 8 --tolerances --json "$out/speed_accuracy_100k_fixed_8_substeps_${gpu}.json"
      $sa --iterations --tolerance-iterations 1 --max-iterations 12 --tolerances 0.02 0.01 0.005 \
        --json "$out/speed_accuracy_100k_subpasses_i1_${gpu}.json"
      $sa --iterations --tolerance-iterations 1 --max-iterations 16 --tolerances 0.0025 \
        --json "$out/speed_accuracy_100k_subpasses_i1_tolerance_0.0025_${gpu}.json"
      $sa --iterations --tolerance-iterations 8 --tolerances 0.02 0.01 0.005 \
        --json "$out/speed_accuracy_100k_iteration_tolerance_${gpu}.json"
      $sa --iterations --tolerance-iterations 2 --max-iterations 4 --tolerances 0.02 0.01 0.005 \
        --json "$out/speed_accuracy_100k_subpasses_i2_${gpu}.json" ;;
    tolerance-i2)
      # two XPBD iterations with sub-passes against the fixed counts, one session
      sa="python3 -W ignore -m benchmarks speed_accuracy --per-l 40 --depth 31 --sample-every 6 --substeps 8"
      $sa --iterations 2 3 4 6 8 --tolerances --json "$out/speed_accuracy_100k_fixed_8_substeps_i2_session_${gpu}.json"
      $sa --iterations --tolerance-iterations 2 --max-iterations 4 --tolerances 0.02 0.01 0.005 \
        --json "$out/speed_accuracy_100k_subpasses_i2_${gpu}.json" ;;
    surge)
      # the surge front at finer resolutions than the CPU runs of docs/archive/validation_notebook.md
      python3 -m benchmarks validate_dam_break --resolutions 40 60 80 --json "$out/koshizuka_oka_${gpu}.json" 2>&1 | grep -v '^Module' ;;
    diffuse)
      # the same run with diffuse particles on (25,000 capacity), against the plain one of 'bench'
      python3 -m benchmarks dam_break --max-diffuse-particles 25000 --trials 3 --json "$out/dam_break_100k_diffuse.json" 2>&1 | grep -A1 "^device" ;;
    worlds)
      # batched worlds: env-steps/s against world count (docs/batched.rst, docs/images/batched_worlds.png)
      bw="python3 -W ignore -m benchmarks batched_worlds"
      $bw --scene pouring --worlds 1 16 256 1024 4096 --per-world 1000 --frames 20 --warmup 5 \
        --json "$out/batched_pouring_1000_${gpu}.json" 2>&1 | grep -v '^Module'
      $bw --scene pouring --worlds 4096 --per-world 1000 --frames 20 --warmup 5 --task-frames 220 \
        --json "$out/batched_pouring_1000_4096_task_${gpu}.json" 2>&1 | grep -v '^Module'
      $bw --scene pouring --worlds 4096 --per-world 1000 --collide-every 2 --frames 20 --warmup 5 --task-frames 220 \
        --json "$out/batched_pouring_1000_k2_${gpu}.json" 2>&1 | grep -v '^Module'
      $bw --scene pouring --worlds 1 16 256 1024 --per-world 4000 --frames 20 --warmup 5 \
        --json "$out/batched_pouring_4000_${gpu}.json" 2>&1 | grep -v '^Module'
      $bw --scene pouring --worlds 4096 --per-world 4000 --frames 10 --warmup 3 \
        --json "$out/batched_pouring_4000_4096_${gpu}.json" 2>&1 | grep -v '^Module'
      $bw --scene multiworld --worlds 1 16 256 1024 4096 --per-world 1000 --frames 20 --warmup 5 \
        --json "$out/batched_multiworld_1000_${gpu}.json" 2>&1 | grep -v '^Module'
      $bw --scene multiworld --worlds 1 16 256 1024 --per-world 4000 --frames 20 --warmup 5 \
        --json "$out/batched_multiworld_4000_${gpu}.json" 2>&1 | grep -v '^Module'
      $bw --scene multiworld --worlds 4096 --per-world 4000 --frames 10 --warmup 3 \
        --json "$out/batched_multiworld_4000_4096_${gpu}.json" 2>&1 | grep -v '^Module'
      $bw --scene pouring --worlds 4096 --per-world 1000 --frames 10 --warmup 5 --breakdown --top 14 \
        --json "$out/batched_pouring_breakdown_${gpu}.json" 2>&1 | grep -v '^Module'
      $bw --from-json "$out"/batched_pouring_1000_${gpu}.json "$out"/batched_pouring_4000_${gpu}.json \
        "$out"/batched_pouring_4000_4096_${gpu}.json "$out"/batched_pouring_1000_k2_${gpu}.json \
        "$out"/batched_multiworld_1000_${gpu}.json "$out"/batched_multiworld_4000_${gpu}.json \
        "$out"/batched_multiworld_4000_4096_${gpu}.json --plot "$out/batched_worlds.png" ;;
    gallery)
      # every example at today's defaults, captured at its default particle count (1280x720, 30 fps from 60 Hz), its
      # last frame kept:
      # the stills of docs/gallery.rst and the capture throughput of docs/archive/performance_notebook.md.
      # GALLERY_ONLY="name ..." limits it to some examples (in that order).
      specs=("dam_break 60" "foam 27" "multiworld 120" "interactive_tank 150" "multi_fluid_tank 300"
             "sdf_container 45" "wave_pool 240" "cup_transfer 270" "archimedes_screw 270")
      for only in ${GALLERY_ONLY:-}; do for spec in "${specs[@]}"; do [[ $spec == "$only "* ]] && picked+=("$spec"); done; done
      for spec in "${picked[@]:-${specs[@]}}"; do
        read -r name frames <<< "$spec"
        echo "== $name ($frames frames)"
        PYGLET_HEADLESS=1 python3 -m newton.examples "fluid_xpbd_$name" --capture "$out/$name.mp4" \
          --capture-still "$out/$name.png" --num-frames "$frames" 2>&1 | grep -v '^Module' | tr '\r' '\n' | tail -2
        rm -f "$out/$name.mp4"
        # one archive, grown per example: the device hands back only a few files per command
        (cd "$out" && tar rf gallery.tar "$name.png" "$name.mp4.json" && rm -f "$name.png" "$name.mp4.json")
      done ;;
    gltests)
      # the image tests on NVIDIA's GL (the resize test needs Xvfb, which GPU machines lack); the
      # CUDA variant of the compute/raster comparison goes through CUDA-GL shared buffers there
      python3 -m pytest -q -rs newton/tests/test_fluid_render_gl.py -k "not resize" 2>&1 | tail -15 ;;
    usd)
      # log_fluid's surface mesh (ViewerUSD): the extraction's cost at the dam break's 100k particles
      # (docs/archive/performance_notebook.md, "Surface mesh"); needs usd-core (pxr), else add --no-usd for the timing alone
      python3 -m benchmarks usd_surface --frames 30 --json "$out/usd_surface_100k_${gpu}.json" 2>&1 | grep -v '^Module' ;;
    tests)
      cuda_tests all ;;
  esac
  [ $poly6_default = 1 ] && git apply "$default_patch"
done
