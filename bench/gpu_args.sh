# The options bench/gpu.sh and bench/gpu_tune.sh share, sourced by both (gpu_tune.sh's carried
# copy has this file beside it). gpu_args NAME ARGS... sets out, quick, emulate, budget (kept
# when the caller set a default), build and build_only, or exits 2 naming the argument.
gpu_args() {
    local name=$1
    shift
    out=""
    quick=0
    emulate=0
    build=1
    build_only=0
    while [ $# -gt 0 ]; do
        case "$1" in
        --out)
            [ $# -ge 2 ] || { echo "$name: --out needs a folder" >&2; exit 2; }
            out=$2
            shift 2
            ;;
        --quick) quick=1; shift ;;
        --emulate) emulate=1; shift ;;
        --no-build) build=0; shift ;;
        --build-only) build_only=1; shift ;;
        --budget)
            [ $# -ge 2 ] && [[ "$2" =~ ^[0-9]+$ ]] ||
                { echo "$name: --budget needs a whole number of seconds" >&2; exit 2; }
            budget=$2
            shift 2
            ;;
        *)
            echo "$name: unknown argument '$1' (allowed: --out DIR, --quick, --emulate," \
                "--budget S, --no-build, --build-only)" >&2
            exit 2
            ;;
        esac
    done
}
