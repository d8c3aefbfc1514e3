#!/usr/bin/env bash
# The main job (README's first command, after the bootstrap): the thesis mass-loss test at the
# first critical speed (section 8.5.3, figures 8.11-8.12) through the real nodes over DDS.
#   1. on-line identification of the wavelet-domain model at that speed (section 6.4),
#   2. 430 g cm mass loss at the non-driven-end disk, PID only,
#   3. the same with PID + wavelet transient control (w = v = 0.75, delay 2, Haar, p = 1),
#   4. the receding-horizon (predictive) controller on the same Haar coefficients with a
#      sinusoidal force (output_basis sinusoid, its model identified on-line too; issue 18),
#   5. the same with the early action on a sudden unbalance (amb-early-model's FE-route model
#      of the rig at the speed; issue 18 item 4),
#   6. one report comparing the four bags (figures, metrics.json, comparison.md).
# Every step is amb-run: plant_sim, wavelet_filterbank, fault_monitor, wavelet_controller and
# the recorder as separate processes, lock-step, parameters from config/amb_params.yaml.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${OUT:-out/demo}"
rm -rf "$OUT"
mkdir -p "$OUT"
SCENARIO=mass_loss_first_critical.yaml
start=$(date +%s)

echo "[demo] 1/7 on-line identification at the first critical speed (PID only, ~30 s simulated)"
amb-run --scenario identification_first_critical.yaml --out "$OUT/identification" \
  --controller transient --without fault_monitor \
  --set wavelet_controller.start_mode:=identify \
  --set "wavelet_controller.model_file_out:=$PWD/$OUT/model.npz"
[ -f "$OUT/model.npz" ] || { echo "[demo] identification wrote no model: see $OUT/identification/logs" >&2; exit 1; }

echo "[demo] 2/7 mass loss, PID only"
amb-run --scenario "$SCENARIO" --out "$OUT/pid_only" --controller none

echo "[demo] 3/7 mass loss, PID + wavelet transient control"
amb-run --scenario "$SCENARIO" --out "$OUT/transient" --controller transient \
  --set "wavelet_controller.model_file:=$PWD/$OUT/model.npz" \
  --set wavelet_controller.start_mode:=active

echo "[demo] 4/7 on-line identification for the sinusoidal force of the predictive controller (PID only, ~30 s simulated)"
amb-run --scenario identification_first_critical.yaml --out "$OUT/identification_sinusoid" \
  --controller transient --without fault_monitor \
  --set wavelet_controller.output_basis:=sinusoid \
  --set wavelet_controller.start_mode:=identify \
  --set "wavelet_controller.model_file_out:=$PWD/$OUT/model_sinusoid.npz"
[ -f "$OUT/model_sinusoid.npz" ] || { echo "[demo] identification wrote no model: see $OUT/identification_sinusoid/logs" >&2; exit 1; }

echo "[demo] 5/7 mass loss, PID + predictive control (identified model, sinusoidal force)"
amb-run --scenario "$SCENARIO" --out "$OUT/predictive" --controller predictive \
  --set wavelet_controller.output_basis:=sinusoid \
  --set "wavelet_controller.model_file:=$PWD/$OUT/model_sinusoid.npz" \
  --set wavelet_controller.start_mode:=active

echo "[demo] 6/7 mass loss, PID + predictive control + early action (FE-route model of the rig at the speed)"
amb-early-model --scenario "config/scenarios/$SCENARIO" --out "$OUT/early_model.npz"
amb-run --scenario "$SCENARIO" --out "$OUT/predictive_early" --controller predictive \
  --set wavelet_controller.output_basis:=sinusoid \
  --set "wavelet_controller.model_file:=$PWD/$OUT/model_sinusoid.npz" \
  --set "wavelet_controller.early_model_file:=$PWD/$OUT/early_model.npz" \
  --set wavelet_controller.start_mode:=active

echo "[demo] 7/7 report"
if command -v amb-report >/dev/null 2>&1; then
  amb-report "$OUT/pid_only/bag" "$OUT/transient/bag" "$OUT/predictive/bag" \
    "$OUT/predictive_early/bag" \
    --labels "PID only,PID + wavelet transient (thesis),PID + predictive (sinusoidal force),PID + predictive + early action" \
    --scenario "config/scenarios/$SCENARIO" --out "$OUT/report"
  echo
  [ -f "$OUT/report/comparison.md" ] && cat "$OUT/report/comparison.md"
  echo "[demo] report: $OUT/report/report.md (figures and metrics.json beside it)"
else
  echo "[demo] amb-report is not built yet: bags are in $OUT/pid_only/bag, $OUT/transient/bag, $OUT/predictive/bag and $OUT/predictive_early/bag"
fi
echo "[demo] done in $(( $(date +%s) - start )) s"
