# Sourced by setup_debian.sh and run_tests.sh: picks the Python interpreter for aos in AOS_PYTHON.
# The python3 on PATH is used unless it is Debian's externally managed one (PEP 668), in which
# case a virtual environment at /opt/aos-venv is used (created on first use).
if [[ -z "${AOS_PYTHON:-}" ]]; then
  if python3 -c 'import os, sys, sysconfig
managed = os.path.exists(os.path.join(sysconfig.get_path("stdlib"), "EXTERNALLY-MANAGED"))
sys.exit(1 if managed and sys.prefix == sys.base_prefix else 0)'; then
    AOS_PYTHON="$(command -v python3)"
  else
    [[ -x /opt/aos-venv/bin/python ]] || python3 -m venv /opt/aos-venv
    AOS_PYTHON=/opt/aos-venv/bin/python
  fi
fi
export AOS_PYTHON
