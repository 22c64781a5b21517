#!/usr/bin/env bash
# No tracked file over 1 MB without a stated reason: whatever is committed is in every
# clone for good (a 10 MB wheel once took three quarters of the tracked bytes, and
# nothing used it). A file that must be large stands in .ci/large-files.txt, one line
# each: its path, then why. Checks the committed tree (HEAD): what a clone gets.
set -euo pipefail
cd "$(dirname "$0")/.."
LIMIT=$((1024 * 1024))
ALLOWED=.ci/large-files.txt

declare -A reason=()
if [[ -f $ALLOWED ]]; then
    while IFS= read -r line; do
        [[ -z ${line// } || $line == \#* ]] && continue
        path=${line%%[[:space:]]*}
        why=$(sed -E 's/^[^[:space:]]+[[:space:]]*//' <<<"$line")
        if [[ -z $why || $why == "$line" ]]; then
            echo "$ALLOWED: '$path' is listed without a reason" >&2
            exit 1
        fi
        reason[$path]=$why
    done <"$ALLOWED"
fi

status=0
while IFS=$'\t' read -r -d '' meta path; do
    size=${meta##* }
    if (( size > LIMIT )) && [[ -z ${reason[$path]:-} ]]; then
        echo "$path: $((size / 1024)) kB tracked, over 1 MB with no reason in $ALLOWED" >&2
        status=1
    fi
done < <(git ls-tree -r -l -z --full-tree HEAD)
exit $status
