# Shared by the peer scripts (tools/check_*.sh, tools/peers/*.sh); source it,
# don't run it. Each script keeps its own venv (gitignored) so that one
# peer's packages never change another's.
#
#   peer_venv DIR "MODULE[, MODULE]" PACKAGE...
#       Makes sure `DIR/bin/python -c "import MODULE, ..."` works: on the
#       first use (or when a module is missing) creates the venv at DIR and
#       installs PACKAGEs from PyPI (needs python3 with venv, and network).
#   echofield_release ROOT
#       Builds the release `echofield` of the workspace at ROOT and sets
#       $echofield to the binary (under $CARGO_TARGET_DIR when set).

peer_venv() {
  local dir="$1" modules="$2"
  shift 2
  if [ ! -x "$dir/bin/python" ] || ! "$dir/bin/python" -c "import $modules" 2>/dev/null; then
    echo "creating $dir with $* from PyPI" >&2
    python3 -m venv "$dir"
    "$dir/bin/pip" install --quiet --upgrade pip
    "$dir/bin/pip" install --quiet "$@"
  fi
}

echofield_release() {
  local root="$1"
  cargo build --quiet --release -p echofield --manifest-path "$root/Cargo.toml"
  echofield="${CARGO_TARGET_DIR:-$root/target}/release/echofield"
}
