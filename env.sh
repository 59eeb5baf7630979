# Source this file (bash) to use the repository: virtual environment + built ROS workspace.
#   source env.sh
_te_root="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck disable=SC1091
source "$_te_root/.venv/bin/activate"
export AMENT_PREFIX_PATH="$_te_root/.venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
# colcon's setup scripts reference unset variables; relax nounset while sourcing them
_te_nounset=0; case $- in *u*) _te_nounset=1; set +u;; esac
# shellcheck disable=SC1091
source "$_te_root/ros2_ws/install/setup.bash"
[ "$_te_nounset" = 1 ] && set -u
# console scripts (tire-estimation, estimator_node, detector_node); `ros2 run` looks there too
export PATH="$_te_root/ros2_ws/install/tire_estimation/lib/tire_estimation:$PATH"
# keep DDS discovery on this machine
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
unset _te_root _te_nounset
