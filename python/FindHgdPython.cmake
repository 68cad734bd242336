# Finds the Python the module is built for, and pybind11; sets HGD_PYTHON_DEFAULT (both found).
#
# The interpreter: -DPython3_EXECUTABLE=... when given; otherwise the first of `python3` on the
# PATH and /usr/bin/python3 that imports numpy (Debian's python3-numpy, python3-pytest and
# python3-open3d serve /usr/bin/python3, while a PATH may lead to another Python first, such as a
# pyenv shim without them), else FindPython3's own choice.
if(NOT Python3_EXECUTABLE)
  find_program(HGD_PATH_PYTHON3 NAMES python3)
  foreach(candidate IN ITEMS "${HGD_PATH_PYTHON3}" /usr/bin/python3)
    if(candidate AND EXISTS "${candidate}")
      execute_process(COMMAND "${candidate}" -c "import numpy" RESULT_VARIABLE status OUTPUT_QUIET ERROR_QUIET)
      if(status EQUAL 0)
        set(Python3_EXECUTABLE "${candidate}" CACHE FILEPATH "The Python the hgdeform module is built for")
        break()
      endif()
    endif()
  endforeach()
endif()
find_package(Python3 3.7 QUIET COMPONENTS Interpreter Development.Module)
# With Python3 found first, pybind11's config builds for that interpreter (its FindPython mode).
if(Python3_FOUND)
  find_package(pybind11 2.6 QUIET CONFIG)
endif()
if(Python3_FOUND AND pybind11_FOUND)
  set(HGD_PYTHON_DEFAULT ON)
else()
  set(HGD_PYTHON_DEFAULT OFF)
endif()
