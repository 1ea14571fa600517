#!/bin/sh
# Rebuild ../three.min.js: the parts of three.js that the report's 3D view uses (entry.mjs),
# bundled with esbuild into one classic script, global MeshfitThree. The three.js release is
# the one viser's client is built with (viser/client/package-lock.json).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
THREE=0.186.0
ESBUILD=0.25.12
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
npm init -y >/dev/null
npm install --no-audit --no-fund "three@$THREE" "esbuild@$ESBUILD" >/dev/null
cp "$here/entry.mjs" .
./node_modules/.bin/esbuild entry.mjs --bundle --minify --format=iife \
  --global-name=MeshfitThree --legal-comments=eof --outfile="$here/../three.min.js"
cp node_modules/three/LICENSE "$here/../three.LICENSE.txt"
