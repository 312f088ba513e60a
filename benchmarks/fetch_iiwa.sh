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
mkdir -p "$DEST"
DEST=$(cd "$DEST" && pwd)
if [ -d "$SOURCE" ] && git -C "$SOURCE" rev-parse --git-dir >/dev/null 2>&1; then
    REPO=$SOURCE
else
    REPO="$DEST/.clone"
    [ -d "$REPO" ] || git clone --bare --filter=blob:none "$SOURCE" "$REPO"
fi
# the archive to a file first: sh has no pipefail, and a failed `git archive | tar` would leave a
# partial folder behind a zero exit status
ARCHIVE="$DEST/.iiwa.tar"
git -C "$REPO" archive -o "$ARCHIVE" "$COMMIT" iiwa_description LICENSE
tar -x -C "$DEST" -f "$ARCHIVE"
rm -f "$ARCHIVE"
echo "iiwa_description at $DEST (IFL-CAMP/iiwa_stack commit $COMMIT)"
