# Source this file to use the set-up venv by hand:  source scripts/env.sh
# Nothing here is required: rclpy and sik_interfaces work in the venv without any variable (the
# ROS wheels set their library path themselves). It activates the venv, selects Fast DDS (the only
# RMW the wheels ship) and puts the venv on AMENT_PREFIX_PATH so that ament_index_python finds
# the packages installed there (sik_ros, sik_interfaces, the message packages).
_sik_repo="$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")/.." && pwd)"
_sik_venv="${VENV:-$_sik_repo/.venv}"
if [ ! -x "$_sik_venv/bin/python" ]; then
  echo "no venv at $_sik_venv: run 'make setup' first" >&2
else
  # shellcheck disable=SC1091
  . "$_sik_venv/bin/activate"
  export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
  case ":${AMENT_PREFIX_PATH:-}:" in
    *":$_sik_venv:"*) ;;
    *) export AMENT_PREFIX_PATH="$_sik_venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}" ;;
  esac
fi
unset _sik_repo _sik_venv
