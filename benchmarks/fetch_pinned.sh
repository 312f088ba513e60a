#!/bin/sh
# Extract PATH... of a public repository at a pinned commit into DEST (the shared step of
# fetch_iiwa.sh and fetch_figaroh_examples.sh; nothing fetched is shipped with ident).
#
#   sh benchmarks/fetch_pinned.sh DEST SOURCE COMMIT PATH...
#
# SOURCE: a git URL (cloned bare, blobs on demand, into DEST/.clone) or a local clone.
set -eu
DEST=${1:?usage: fetch_pinned.sh DEST SOURCE COMMIT PATH...}
SOURCE=${2:?usage: fetch_pinned.sh DEST SOURCE COMMIT PATH...}
COMMIT=${3:?usage: fetch_pinned.sh DEST SOURCE COMMIT PATH...}
shift 3
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
ARCHIVE="$DEST/.fetch.tar"
git -C "$REPO" archive -o "$ARCHIVE" "$COMMIT" "$@"
tar -x -C "$DEST" -f "$ARCHIVE"
rm -f "$ARCHIVE"
