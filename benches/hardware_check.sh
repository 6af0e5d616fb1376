#!/usr/bin/env bash
# The hardware check of docs/gpu.md ("Measured on hardware"): one command that measures a
# built cdlab on the machine's GPU beside its CPU and writes report.json and report.md.
#
#   benches/hardware_check.sh CDLAB OUT [SAMPLE]
#
# CDLAB is the binary (build it with `cargo build --release`; strip it to carry it), OUT a
# directory for the report and the logs, SAMPLE a 5000-disk sample from `cdlab prepare`
# (prepared on the CPU beforehand, so that both backends start the 5000-disk test from the
# same packing; without it the test deposits and compacts on each backend). Each part has
# its own time limit and a failed part does not stop the others; the report lists every
# part with its exit status and wall time. Limits (seconds) and sizes can be set:
#   CDLAB_HW_BENCH_DISKS  sample sizes of the bench (5000,20000,50000; 0 leaves it out)
#   CDLAB_HW_CHECK_EVERY  convergence-test intervals the bench compares (0,1,4,16; 0 is the
#                         default: 8 on the GPU, 1 on the CPU)
#   CDLAB_HW_METHODS      solver methods the bench compares (colored-gs,jacobi)
#   CDLAB_HW_RECORD_THREADS  host threads recording the GPU's steps, compared by the bench
#                         (1,2,4,0; 0 is the backend's choice)
#   CDLAB_HW_SWEEP_ALL    whether the bench sweeps iterations past the typical count in one
#                         workgroup, compared (true,false)
#   CDLAB_HW_BASELINE     another cdlab binary (an earlier version) benched on the GPU at
#                         CDLAB_HW_BASELINE_DISKS (5000,50000) in the same run, for a ratio
#   CDLAB_HW_PINNED       cores (2 or more) of a CPU bench pinned with taskset to cores 2..,
#                         at CDLAB_HW_PINNED_DISKS (5000,50000), 40 steps, 3 rounds: the
#                         ratio between sizes of docs/benchmarks.md ("The ratios over
#                         rounds") on a quiet host (0, the default, leaves it out)
#   CDLAB_HW_CPU_THREADS  threads of the 5000-disk CPU test, which runs beside the GPU one
#                         (the cores less 4: the GPU test's host thread needs one)
#   CDLAB_HW_STRAIN       end strain of the 5000-disk tests (0.02)
#   CDLAB_HW_TEST_S       limit of each 5000-disk test (150; 0 leaves both out)
#   CDLAB_HW_CPU_TEST     0 leaves out the 5000-disk test on the CPU (1)
#   CDLAB_HW_LARGE_S      wall time given to the 50,000-disk GPU test (90; 0 leaves it out)
#   CDLAB_HW_LARGE_DISKS  its size (50000)
#   CDLAB_HW_LARGE_SAMPLE a prepared sample the large test starts from instead (its size
#                         is the sample's; without one the test deposits and compacts)
#   CDLAB_HW_LARGE_CPU    1 runs the large test on the CPU too, beside the GPU's, on
#                         CDLAB_HW_CPU_THREADS threads (0)
#   CDLAB_HW_CROSSOVER    prepared samples, comma separated, each tested from its start
#                         on the GPU (host threads on cores 0-3) beside the CPU on 2 threads
#                         (cores 4-5; unpinned on fewer than 6 cores), then on the CPU
#                         alone with its default threads: the sizes around `auto`'s
#                         threshold (docs/gpu.md, "Choosing the backend") on this machine
#                         (none by default)
#   CDLAB_HW_CROSSOVER_S  limit of each of those tests (60), to CDLAB_HW_CROSSOVER_STRAIN
#                         (0.004)
# The whole check takes about 8 minutes on a data-centre GPU with its defaults.
set -uo pipefail
if [ $# -lt 2 ]; then
    echo "usage: $0 CDLAB OUT [SAMPLE]" >&2
    exit 2
fi
BIN="$(realpath "$1")"
OUT="$2"
SAMPLE="${3:-}"
HERE="$(cd "$(dirname "$0")" && pwd)"
mkdir -p "$OUT"
OUT="$(realpath "$OUT")"
export WGPU_BACKEND="${WGPU_BACKEND:-vulkan}"
if [ -z "${XDG_RUNTIME_DIR:-}" ]; then
    XDG_RUNTIME_DIR="$(mktemp -d)"
    export XDG_RUNTIME_DIR
fi
DISKS="${CDLAB_HW_BENCH_DISKS:-5000,20000,50000}"
STRAIN="${CDLAB_HW_STRAIN:-0.02}"
TEST_S="${CDLAB_HW_TEST_S:-150}"
LARGE_S="${CDLAB_HW_LARGE_S:-90}"
LARGE_DISKS="${CDLAB_HW_LARGE_DISKS:-50000}"
EVERY="${CDLAB_HW_CHECK_EVERY:-0,1,4,16}"
CORES="$(nproc)"
CPU_THREADS="${CDLAB_HW_CPU_THREADS:-$(( CORES > 5 ? CORES - 4 : 1 ))}"
printf 'part\trc\tseconds\tlimit_s\n' >"$OUT/parts.tsv"

# part NAME LIMIT_S COMMAND...: runs COMMAND with its output in OUT/NAME.log; at the limit
# it gets SIGINT (cdlab then stops at the next step and closes its record), and SIGKILL 30 s
# later.
part() {
    local name=$1 limit=$2
    shift 2
    echo "== $name (limit ${limit} s)"
    local t0 t1 rc
    t0=$(date +%s%N)
    timeout -s INT -k 30 "$limit" "$@" >"$OUT/$name.log" 2>&1
    rc=$?
    t1=$(date +%s%N)
    local secs=$(( (t1 - t0) / 1000000 ))
    printf '%s\t%d\t%d.%03d\t%s\n' "$name" "$rc" $((secs / 1000)) $((secs % 1000)) "$limit" >>"$OUT/parts.tsv"
    tail -n 3 "$OUT/$name.log"
}

part info 60 "$BIN" info --json
cp "$OUT/info.log" "$OUT/info.json"
if command -v nvidia-smi >/dev/null; then
    nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.max.sm --format=csv >"$OUT/nvidia-smi.csv" 2>&1
fi
nproc >"$OUT/cores.txt"

# One bench for both backends: each sample is deposited once for all its cases.
[ "$DISKS" = 0 ] || part bench 300 "$BIN" bench --disks "$DISKS" --backend gpu,cpu --check-every "$EVERY" \
    --method "${CDLAB_HW_METHODS:-colored-gs,jacobi}" \
    --record-threads "${CDLAB_HW_RECORD_THREADS:-1,2,4,0}" --sweep-all "${CDLAB_HW_SWEEP_ALL:-true,false}" \
    --out "$OUT/bench"
PINNED="${CDLAB_HW_PINNED:-0}"
if [ "$PINNED" -ge 2 ] && command -v taskset >/dev/null; then
    # Cores 0 and 1 take most of the host's interrupts; the team runs beside them.
    part bench_cpu_pinned 240 taskset -c "$(seq -s, 2 $((PINNED + 1)))" "$BIN" bench \
        --disks "${CDLAB_HW_PINNED_DISKS:-5000,50000}" --backend cpu --steps 40 --rounds 3 \
        --out "$OUT/bench_cpu_pinned"
fi
if [ -n "${CDLAB_HW_BASELINE:-}" ]; then
    part bench_baseline 180 "$(realpath "$CDLAB_HW_BASELINE")" bench \
        --disks "${CDLAB_HW_BASELINE_DISKS:-5000,50000}" --backend gpu --out "$OUT/bench_baseline"
fi

from=()
if [ -n "$SAMPLE" ]; then from=(--sample "$(realpath "$SAMPLE")"); else from=(--disks 5000); fi
# The CPU's tests run beside the GPU's: the GPU test's host threads and the CPU test's team
# share the cores (CPU_THREADS for the CPU test).
"$BIN" config --print-default | sed "s/^threads = 0/threads = $CPU_THREADS/" >"$OUT/cpu_test.toml"
if [ "$TEST_S" != 0 ]; then
    if [ "${CDLAB_HW_CPU_TEST:-1}" != 0 ]; then
        part test5000_cpu "$TEST_S" "$BIN" biaxial --config "$OUT/cpu_test.toml" "${from[@]}" \
            --strain "$STRAIN" --backend cpu --out "$OUT/test5000_cpu" --force --no-figures &
    fi
    part test5000_gpu "$TEST_S" "$BIN" biaxial "${from[@]}" --strain "$STRAIN" --backend gpu \
        --out "$OUT/test5000_gpu" --force --no-figures
    wait
fi
if [ -n "${CDLAB_HW_CROSSOVER:-}" ]; then
    # Pinned apart where the host has the cores, so that neither test slows the other.
    pin_gpu=() pin_cpu=()
    if [ "$CORES" -ge 6 ] && command -v taskset >/dev/null; then
        pin_gpu=(taskset -c 0-3) pin_cpu=(taskset -c 4,5)
    fi
    "$BIN" config --print-default | sed "s/^threads = 0/threads = 2/" >"$OUT/cpu2_test.toml"
    IFS=, read -ra cross <<<"$CDLAB_HW_CROSSOVER"
    for s in "${cross[@]}"; do
        name="$(basename "$s" .sample)"
        args=(--sample "$(realpath "$s")" --strain "${CDLAB_HW_CROSSOVER_STRAIN:-0.004}" --force --no-figures)
        part "test_x_${name}_cpu2" "${CDLAB_HW_CROSSOVER_S:-60}" ${pin_cpu[@]+"${pin_cpu[@]}"} "$BIN" biaxial \
            --config "$OUT/cpu2_test.toml" "${args[@]}" --backend cpu --out "$OUT/test_x_${name}_cpu2" &
        part "test_x_${name}_gpu" "${CDLAB_HW_CROSSOVER_S:-60}" ${pin_gpu[@]+"${pin_gpu[@]}"} "$BIN" biaxial \
            "${args[@]}" --backend gpu --out "$OUT/test_x_${name}_gpu"
        wait
        part "test_x_${name}_cpu" "${CDLAB_HW_CROSSOVER_S:-60}" "$BIN" biaxial "${args[@]}" \
            --backend cpu --out "$OUT/test_x_${name}_cpu"
    done
fi
if [ "$LARGE_S" != 0 ]; then
    large=(--disks "$LARGE_DISKS")
    if [ -n "${CDLAB_HW_LARGE_SAMPLE:-}" ]; then large=(--sample "$(realpath "$CDLAB_HW_LARGE_SAMPLE")"); fi
    if [ "${CDLAB_HW_LARGE_CPU:-0}" != 0 ]; then
        part test_large_cpu "$LARGE_S" "$BIN" biaxial --config "$OUT/cpu_test.toml" "${large[@]}" \
            --backend cpu --out "$OUT/test_large_cpu" --force --no-figures &
    fi
    part test_large_gpu "$LARGE_S" "$BIN" biaxial "${large[@]}" --backend gpu \
        --out "$OUT/test_large_gpu" --force --no-figures
    wait
fi

python3 "$HERE/hardware_report.py" "$OUT"
