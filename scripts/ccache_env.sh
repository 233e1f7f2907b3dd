# Sourced by the build scripts: ccache's cache and how it keys compilations. Paths are taken
# relative to the checkout, so another clone (CI) or work tree reuses the cache. Needs the
# working directory to be the checkout's root.
export CCACHE_DIR="${CCACHE_DIR:-$HOME/.cache/fourd-ccache}"
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$PWD}"
export CCACHE_NOHASHDIR=1
