# Sourced by every script of benchmarks/: the binary, the output folder and
# the machine, printed first so that every result says where it was taken.
# Run from the repository's root after `cargo build --release -p etp`
# (`etp run` finds its processes next to the binary or plays them itself).
ETP=${ETP:-target/release/etp}
if [ ! -x "$ETP" ]; then
  echo "benchmarks: $ETP is missing: cargo build --release -p etp" >&2
  exit 1
fi
OUT=${OUT:-target/benchmarks/$(basename "$0" .sh)}
mkdir -p "$OUT"
echo "machine: $(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GiB", $2 / 1048576}' /proc/meminfo), load $(cut -d' ' -f1-3 /proc/loadavg); results in $OUT" >&2
# A seconds clock for wall times.
now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }'; }
