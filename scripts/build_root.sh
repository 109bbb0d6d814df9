# Sourced by setup.sh and test.sh: build_root VENV_DIR prints the folder of that environment's
# CMake build, build/<venv name>-<hash of its absolute path>. Two venvs installed from one clone
# would otherwise share build/{wheel_tag} and rebuild each other from scratch; the hash keeps
# two venvs of one name in different places apart.
build_root() {
  local abs name
  abs="$(cd "$1" && pwd)"
  name="$(basename "$abs" | sed 's/^\.*//')"
  printf 'build/%s-%s' "${name:-venv}" "$(printf '%s' "$abs" | sha1sum | cut -c1-8)"
}
