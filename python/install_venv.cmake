# Installs the package `tessera` into a fresh virtual environment VENV exactly as python/README.md
# tells users to (Debian's packages only, no registry), and checks that it imports from there.
# Run by CTest (cmake -DPYTHON=... -DVENV=... -DPACKAGE=... -P install_venv.cmake) as the test
# python.install, which the package's other tests need: they run on VENV/bin/python.
foreach(var PYTHON VENV PACKAGE)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "install_venv.cmake: -D${var}=... is required")
  endif()
endforeach()

# A fresh one each run: nothing of an earlier install (a module since removed) is tested.
file(REMOVE_RECURSE "${VENV}")
execute_process(COMMAND "${PYTHON}" -m venv --system-site-packages "${VENV}" COMMAND_ERROR_IS_FATAL ANY)
execute_process(COMMAND "${VENV}/bin/pip" install --no-deps --no-build-isolation --no-index "${PACKAGE}"
                COMMAND_ERROR_IS_FATAL ANY)

# Imported from the venv's site-packages, stubs included, from a folder that is not the sources.
execute_process(
  COMMAND "${VENV}/bin/python" -c [=[
import os, sys, sysconfig
import tessera, tessera.v1.client_service_pb2_grpc, tessera.v1.ray_service_pb2_grpc
where = os.path.realpath(tessera.__file__)
site = os.path.realpath(sysconfig.get_paths()["purelib"])
print(f"tessera {tessera.__version__} imports from {where}")
sys.exit(0 if where.startswith(site + os.sep) else f"expected it under {site}")
]=]
  WORKING_DIRECTORY "${VENV}"
  COMMAND_ERROR_IS_FATAL ANY)
