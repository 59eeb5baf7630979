"""Print exact pins of the installed distributions that came from package indexes.

``pip freeze`` also lists the ``*.egg-info`` metadata that the ROS 2 wheels embed for their
inner packages (``rclpy``, ``std_msgs``, ...); those are not installable on their own, so only
``*.dist-info`` distributions are pinned. pip/wheel are left out; setuptools is pinned because
colcon's ament_python builds use it.
"""

from __future__ import annotations

import importlib.metadata as md

SKIP = {"pip", "wheel"}


def main() -> None:
    pins = {}
    for dist in md.distributions():
        path = str(getattr(dist, "_path", ""))
        name = dist.metadata["Name"]
        if not path.endswith(".dist-info") or name.lower() in SKIP:
            continue
        pins[name.lower()] = f"{name}=={dist.version}"
    print("# Exact versions installed by scripts/setup.sh ('make lock' regenerates it).")
    for key in sorted(pins):
        print(pins[key])


if __name__ == "__main__":
    main()
