#!/usr/bin/env bash
# Every screen at every tablet size (issue 29): one screenshot per screen, size, density and
# language with `storybeam app --screenshot`, then a table of how many widgets each one
# shows cut off or covered (its JSON's clipped_widgets; 0 everywhere when the layout holds).
#   bash scripts/screen_sizes.sh [OUT_DIR]        (default out/screens; about 10 s a shot)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/screens}
mkdir -p "$out"
py=.venv/bin/python
[ -x "$py" ] || py=python3
printf "%-9s %-14s %-4s %s\n" screen size lang clipped
for size in 1024x600@1 1280x800@1 1280x800@1.33 2560x1600@2 2560x1600@3; do
  for screen in home editor play teacher pin; do
    for lang in en ja; do
      wh=${size%@*}; d=${size#*@}; png="$out/${screen}_${wh}_${d}_${lang}.png"
      rm -f "$out/profile.db"*
      "$py" -m app.cli app --db "$out/profile.db" --screenshot "$png" --screen "$screen" --size "$wh" \
        --density "$d" --lang "$lang" --preview 2d >/dev/null 2>&1
      "$py" -c "import json,sys; c=json.load(open(sys.argv[1]))['clipped_widgets']; print('%-9s %-14s %-4s %d %s' % (sys.argv[2], sys.argv[3], sys.argv[4], len(c), '; '.join(x['widget'] + ': ' + x['problem'] for x in c)))" \
        "$png.json" "$screen" "$size" "$lang"
    done
  done
done
