#!/usr/bin/env bash
# The main job (README's first command, after the bootstrap): the thesis mass-loss
# demonstration. Until the closed loop lands it runs the parts that exist and says so.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${OUT:-out/demo}"
mkdir -p "$OUT"
if python -c "import amb_plant_sim.modal_cli" 2>/dev/null; then
  echo "[demo] rig model: natural frequencies with the local PID (amb-modal)"
  python -m amb_plant_sim.modal_cli --rig config/rig.yaml --plot-dir "$OUT/modal"
  echo "[demo] modal plots in $OUT/modal"
fi
if python -c "import amb_wavelet.info_cli" 2>/dev/null; then
  echo "[demo] wavelet uncertainty measures (thesis table 4.1)"
  python -m amb_wavelet.info_cli --wavelets haar,db2,db4,sym4,coif2
fi
echo "[demo] the closed-loop mass-loss demonstration (PID vs PID + wavelet transient control)"
echo "[demo] is not built yet: see the open issues"
