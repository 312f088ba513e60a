#!/bin/sh
# Fetch FIGAROH's examples (TX40 identification example, its config and data; the UR10 URDF of
# its truth fixture) for benchmarks/bench_peers.py --parts figaroh excitation --figaroh-examples DEST.
#
#   sh benchmarks/fetch_figaroh_examples.sh DEST [SOURCE]
#
# SOURCE: a git URL or a local clone (default: https://github.com/thanhndv212/figaroh-examples).
# The commit is pinned. figaroh-examples is Apache-2.0 (Copyright 2021-2025 Thanh Nguyen,
# 2022-2023 CNRS, Toward SAS); nothing of it is shipped with ident: this script fetches it.
#
# Three path fixes make the pinned example run with figaroh 1.0.2 (the `peers` extra); each is a
# symbolic link, no file of the example is edited:
#  1. its script imports `examples.staubli_tx40` but the folder is `staubli_TX40`;
#  2. its unified config extends `../templates/manipulator_robot.yaml` from `config/`, which
#     resolves to `staubli_TX40/templates` (the templates are in `examples/templates`);
#     that template extends `base_robot_config.yaml`, resolved from the config's folder;
#  3. figaroh's load_robot(package_dirs="models") looks for `./figaroh-examples/models`.
# (Its identification.py names the legacy TX40_config.yaml, which figaroh 1.0 refuses; the
# benchmark uses the example's own unified config, staubli_tx40_unified_config.yaml.)
set -eu
DEST=${1:?usage: fetch_figaroh_examples.sh DEST [SOURCE]}
SOURCE=${2:-https://github.com/thanhndv212/figaroh-examples}
COMMIT=c0b5c7f0fda10078be55104f9ee76ac106b7a5ee
HERE=$(cd "$(dirname "$0")" && pwd)
sh "$HERE/fetch_pinned.sh" "$DEST" "$SOURCE" "$COMMIT" examples/__init__.py examples/staubli_TX40 \
    examples/templates models/staubli_tx40_description examples/ur10/urdf
DEST=$(cd "$DEST" && pwd)
cd "$DEST/examples"
ln -sfn staubli_TX40 staubli_tx40
ln -sfn ../templates staubli_TX40/templates
ln -sfn ../../templates/base_robot_config.yaml staubli_TX40/config/base_robot_config.yaml
ln -sfn "$DEST" staubli_TX40/figaroh-examples
echo "FIGAROH examples at $DEST (commit $COMMIT)"
