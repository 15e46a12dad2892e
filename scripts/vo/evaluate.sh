#!/usr/bin/env bash
# Visual odometry on a TUM sequence: every detector x pipeline through `intellwheels vo`, the
# OpenCV peer (cv2.Odometry RGB_DEPTH) on the same frames, and the third-party `evo` on every
# trajectory (evo_ape -a: ATE RMSE after SE(3) alignment; evo_rpe -a: drift per frame).
#
# Usage: scripts/vo/evaluate.sh BIN SEQ_DIR OUT_DIR [--no-peer]
#   BIN      the intellwheels binary (cargo build --release -p intellwheels: target/release/intellwheels)
#   SEQ_DIR  a TUM-layout folder with groundtruth.txt (e.g. shared/data/tum/rgbd_dataset_freiburg1_rpy)
#   OUT_DIR  trajectories, plots, per-frame stats and summary.tsv go here
# Needs: pip install evo opencv-contrib-python-headless scipy
set -euo pipefail
[ $# -ge 3 ] || { sed -n 2,10p "$0"; exit 2; }
BIN=$1; SEQ=$2; OUT=$3; PEER=${4:-}
GT="$SEQ/groundtruth.txt"
mkdir -p "$OUT"
command -v evo_ape >/dev/null || { echo "evo not found: pip install evo" >&2; exit 2; }

ape() { evo_ape tum "$GT" "$1" -a 2>/dev/null | awk '$1=="rmse"{printf "%.4f", $2}'; }
rpe_t() { evo_rpe tum "$GT" "$1" -a --delta 1 --delta_unit f 2>/dev/null | awk '$1=="rmse"{printf "%.4f", $2}'; }
rpe_r() { evo_rpe tum "$GT" "$1" -a --delta 1 --delta_unit f -r angle_deg 2>/dev/null | awk '$1=="rmse"{printf "%.3f", $2}'; }

printf "method\tours_ate_m\tevo_ate_m\tevo_rpe_m\tevo_rpe_deg\tfps\n" > "$OUT/summary.tsv"
for pipeline in thesis keyframe; do
  for detector in lsac-surf surf ln-surf; do
    name="$detector-$pipeline"
    "$BIN" vo "$SEQ" --detector "$detector" --pipeline "$pipeline" -o "$OUT/$name.txt" \
      --plot "$OUT/$name.png" --stats "$OUT/$name.stats.jsonl" --json > "$OUT/$name.json"
    ours=$(python3 -c "import json,sys; print('%.4f' % json.load(open(sys.argv[1]))['ate_rmse_m'])" "$OUT/$name.json")
    fps=$(python3 -c "import json,sys; print('%.1f' % json.load(open(sys.argv[1]))['fps'])" "$OUT/$name.json")
    printf "%s\t%s\t%s\t%s\t%s\t%s\n" "$name" "$ours" "$(ape "$OUT/$name.txt")" "$(rpe_t "$OUT/$name.txt")" "$(rpe_r "$OUT/$name.txt")" "$fps" | tee -a "$OUT/summary.tsv"
  done
done
if [ "$PEER" != "--no-peer" ]; then
  line=$(python3 "$(dirname "$0")/opencv_odometry.py" "$SEQ" "$OUT/opencv-rgbd.txt")
  echo "$line"
  fps=$(echo "$line" | sed -E 's/.* ([0-9.]+) frames\/s.*/\1/')
  printf "%s\t%s\t%s\t%s\t%s\t%s\n" "opencv-rgbd-odometry" "-" "$(ape "$OUT/opencv-rgbd.txt")" "$(rpe_t "$OUT/opencv-rgbd.txt")" "$(rpe_r "$OUT/opencv-rgbd.txt")" "$fps" | tee -a "$OUT/summary.tsv"
fi
column -t "$OUT/summary.tsv"
