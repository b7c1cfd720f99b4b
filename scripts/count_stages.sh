#!/usr/bin/env bash
# Counts the stages of a staged study: `ribbon plan`, then `run` + `merge` until merge exits 0 or 4.
# Usage: scripts/count_stages.sh RIBBON OUTDIR URDF [analyze options...]
# Prints one line per stage (stage, runs, run seconds, merge seconds) and a total; writes
# OUTDIR/staged.csv and OUTDIR/staged.summary.json from the final merge.
set -u
ribbon=$1; out=$2; urdf=$3; shift 3
rm -rf "$out"; mkdir -p "$out"
plan="$out/study.plan"; dir="$out/shards"
start=$(date +%s.%N)
"$ribbon" plan "$urdf" "$@" --plan "$plan" > "$out/plan.txt" || { echo "plan failed"; exit 1; }
stage=0; run_total=0; merge_total=0
while true; do
  stage=$((stage + 1))
  t0=$(date +%s.%N)
  "$ribbon" run "$plan" --shard 0/1 --into "$dir" > "$out/run-$stage.txt" 2>&1 || { echo "run failed at stage $stage"; cat "$out/run-$stage.txt"; exit 1; }
  t1=$(date +%s.%N)
  "$ribbon" merge "$plan" "$dir" --csv "$out/staged.csv" --summary "$out/staged.summary.json" > "$out/merge-$stage.txt" 2>&1
  code=$?
  t2=$(date +%s.%N)
  runs=$(ls "$dir"/stage-$stage/*.mcap >/dev/null 2>&1 && python3 -c "
import json,sys
p='$dir/stage-$stage/stage.plan' if $stage>1 else '$plan'
b=json.load(open(p))['body']; print(b['samples'] + (1 if b.get('nominal') or b.get('staged',{}).get('nominal') else 0))" 2>/dev/null || echo '?')
  rs=$(echo "$t1 - $t0" | bc); ms=$(echo "$t2 - $t1" | bc)
  run_total=$(echo "$run_total + $rs" | bc); merge_total=$(echo "$merge_total + $ms" | bc)
  printf 'stage %2d: samples %s  run %.2f s  merge %.2f s  exit %d\n' "$stage" "$runs" "$rs" "$ms" "$code"
  case $code in
    3) continue ;;
    0|4) break ;;
    *) echo "merge failed (exit $code)"; cat "$out/merge-$stage.txt"; exit 1 ;;
  esac
done
end=$(date +%s.%N)
printf 'stages %d  run %.1f s  merge %.1f s  wall %.1f s  load: %s\n' "$stage" "$run_total" "$merge_total" "$(echo "$end - $start" | bc)" "$(uptime | sed 's/.*load average: //')"
