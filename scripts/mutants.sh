#!/usr/bin/env bash
# Mutation check: breaks the code on purpose, one named mutation at a time, and runs the tests
# that must catch it. A mutation the tests do not catch is a hole in the suite.
#
#   scripts/mutants.sh            # every mutation; table on stdout, log in target/mutants/
#   scripts/mutants.sh NAME...    # only these
#   MUTANTS_DRY=1 scripts/mutants.sh   # only check that every mutation still applies
#
# Each mutation is a Perl substitution that must match exactly once under src/ (searched by
# pattern, not by file, so that moving code between files does not silently disable it: a
# mutation that no longer matches is reported as "stale" and the script fails). The work is
# done on a copy of the tree under target/mutants/, never on the checkout itself. Only the
# named test targets run per mutation, so a full pass costs one build of the crate plus one
# incremental rebuild and those targets per mutation (about 2–3 minutes each on 2 cores).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
work="$root/target/mutants"
copy="$work/tree"
mkdir -p "$work"
# A fresh copy of the working tree's files that git tracks or would track (not target/).
rm -rf "$copy" && mkdir -p "$copy"
(cd "$root" && git ls-files -z --cached --others --exclude-standard | tar --null -T - -cf -) | (cd "$copy" && tar -xf -)
export CARGO_TARGET_DIR="$work/target"
log="$work/log.txt"
: >"$log"

# name | perl substitution (applied with -0777 to each file under src/) | test targets | what it models
mutations=(
  "pacer-half-rate|s/(start \+ )\((k as u128 \* 1_000_000_000_000_000 \/ self\.frames_per_s_uhz)\) as i128/\$1(2 * \$2) as i128/|realtime|pacer deadlines ×2 (frames at half the rate)"
  "pacer-50ms-late|s/(start \+ \(k as u128 \* 1_000_000_000_000_000 \/ self\.frames_per_s_uhz\) as i128)/\$1 + 50_000_000/|realtime|every frame sent 50 ms late"
  "skipped-not-counted|s/st\.skipped \+= \(from - i\) as u64;/st.skipped += 0;/|realtime|frames skipped by catch-up not counted"
  "dropped-not-counted|s/self\.stats\.dropped \+= ends\.len\(\) as u64;/self.stats.dropped += 0;/g|realtime|frames dropped at a sink (no reader, slow reader) not counted"
  "rate-lsb-noop|s/(let v = &mut s\.rate\(r\)\.0\[i\];\s*)\*v = q\.apply\(\*v\);/\$1let _ = q.apply(*v);/|quantization gauss_markov error_model|rate-LSB quantization (Lsb::Rate) a no-op"
  "gm-euler|s/let phi = \(-dt \/ tau\)\.exp\(\);\n(\s*)\/\/ 1 − e\^\{−2x\} without cancellation for small x\.\n\s*let q = sigma \* \(-\(-2\.0 \* dt \/ tau\)\.exp_m1\(\)\)\.sqrt\(\);/let phi = 1.0 - dt \/ tau;\n\$1let q = sigma * (2.0 * dt \/ tau).sqrt();/|gauss_markov error_model|Gauss–Markov discretised with Euler"
  "gm-noise-105|s/(let q = sigma \* \(-\(-2\.0 \* dt \/ tau\)\.exp_m1\(\)\)\.sqrt\(\));/\$1 * 1.05;/|gauss_markov error_model|Gauss–Markov driving noise ×1.05"
  "generator-late-24h|s/(let t = self\.t0 \+ \(base \+ x\) \/ self\.rate_hz;)/\$1\n                    let t = if t > 86_399.0 { t + 0.05 } else { t };/|closed_form|generator evaluating the motion 50 ms late in the last second of a 24 h run"
  "flicker-sigma-095|s/(let sigma = b \* \(ln_r \/ std::f64::consts::PI\)\.sqrt\(\));/\$1 * 0.95;/|gauss_markov error_model|bias-instability bank σ ×0.95"
)

want=("$@")
status=0
printf '| mutation | what it models | tests run | result |\n|---|---|---|---|\n'
for m in "${mutations[@]}"; do
  IFS='|' read -r name sub tests what <<<"$m"
  if [ ${#want[@]} -gt 0 ] && [[ ! " ${want[*]} " =~ " $name " ]]; then continue; fi
  # Apply: exactly one file under src/ must change.
  changed=()
  while IFS= read -r f; do
    before=$(sha1sum "$copy/$f")
    perl -0777 -i -pe "$sub" "$copy/$f"
    [ "$(sha1sum "$copy/$f")" != "$before" ] && changed+=("$f")
  done < <(cd "$copy" && find src -name '*.rs' | sort)
  targets=""
  for t in $tests; do
    [ -f "$copy/tests/$t.rs" ] && targets="$targets --test $t"
  done
  if [ ${#changed[@]} -ne 1 ] || [ -z "$targets" ]; then
    echo "| $name | $what | $tests | **stale**: the pattern matched ${#changed[@]} files (need 1) or no test target exists |"
    status=1
  elif [ -n "${MUTANTS_DRY:-}" ]; then
    echo "| $name | $what | $tests | applies (${changed[0]}); not run |"
  else
    one="$work/$name.log"
    if (cd "$copy" && cargo test --release --no-fail-fast $targets) >"$one" 2>&1; then
      echo "| $name | $what | $tests | **survived** (${changed[0]}) |"
      status=1
    else
      # The names listed under "failures:" (cargo test prints each failing test once there).
      failed=$(awk '/^failures:$/{f=1;next} f&&/^    [A-Za-z0-9_:]+$/{print $1} /^test result/{f=0}' "$one" | sort -u | tr '\n' ' ')
      echo "| $name | $what | $tests | caught (${changed[0]}): ${failed:-build or harness failure, see $one} |"
    fi
    cat "$one" >>"$log"
  fi
  # Restore the copy.
  for f in "${changed[@]}"; do cp "$root/$f" "$copy/$f"; done
done
exit $status
