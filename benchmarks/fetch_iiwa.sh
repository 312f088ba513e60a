#!/bin/sh
# Fetch the KUKA LBR iiwa 14 description of a ROS workspace (IFL-CAMP/iiwa_stack's
# iiwa_description package: xacro, STL collision and visual meshes, inertials) for
# benchmarks/bench_quickstart.py --zoo iiwa14 --fetched DEST.
#
#   sh benchmarks/fetch_iiwa.sh DEST [SOURCE]
#
# SOURCE: a git URL or a local clone (default: https://github.com/IFL-CAMP/iiwa_stack).
# The commit is pinned. iiwa_stack is BSD-2-Clause (Copyright 2016-2019 Salvatore Virga, Marco
# Esposito, TU Munich); nothing of it is shipped with ident: this script fetches it.
# example-robot-data has no iiwa; this one is the robot as a ROS user has it: `ident init`
# reads DEST/iiwa_description/urdf/iiwa14.urdf.xacro with --package-dir DEST ($(find
# iiwa_description) and package://iiwa_description/ resolve there), no file edited.
set -eu
DEST=${1:?usage: fetch_iiwa.sh DEST [SOURCE]}
SOURCE=${2:-https://github.com/IFL-CAMP/iiwa_stack}
COMMIT=44f9d13c1b444d5dc9fd3e43ba60b7d3b2ea2bbb
HERE=$(cd "$(dirname "$0")" && pwd)
sh "$HERE/fetch_pinned.sh" "$DEST" "$SOURCE" "$COMMIT" iiwa_description LICENSE
DEST=$(cd "$DEST" && pwd)
echo "iiwa_description at $DEST (IFL-CAMP/iiwa_stack commit $COMMIT)"
