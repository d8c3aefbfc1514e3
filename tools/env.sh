# Source this file (bash) to use the workspace by hand: the venv, the colcon install space, the
# source tree on PYTHONPATH, and DDS discovery kept on this machine.
#   source tools/env.sh
_amb_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
unset _ROS_WHEELS_BOOTSTRAP_COMPLETE
# shellcheck disable=SC1091
source "$_amb_root/.venv/bin/activate"
export AMENT_PREFIX_PATH="$_amb_root/.venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
# shellcheck disable=SC1091
source "$_amb_root/install/setup.bash"
export PYTHONPATH="$_amb_root${PYTHONPATH:+:$PYTHONPATH}"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
# The matrices here are small (the plant's are ~130 states): OpenBLAS threads only contend with
# the other nodes on a 2-core machine (docs/results.md#plant-bench: one thread against nproc).
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
export PATH="$_amb_root/install/amb_wavelet_control/lib/amb_wavelet_control:$PATH"
unset _amb_root
