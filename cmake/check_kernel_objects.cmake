# Refuses the per-level copies of the region kernels (CMakeLists.txt) when an object holds a
# symbol that the linker could give a caller compiled for the baseline (anything global but the
# kernels' entries: a weak inline function or template instance compiled with AVX would run on a
# CPU without it) or a static initialiser (run at load, on any CPU).
#   cmake -DNM=<nm> -DOBJECTS=<obj;...> -P check_kernel_objects.cmake
if(NOT NM OR NOT OBJECTS)
  message(FATAL_ERROR "check_kernel_objects: NM and OBJECTS are required")
endif()
foreach(object IN LISTS OBJECTS)
  execute_process(COMMAND ${NM} --defined-only -P ${object}
                  OUTPUT_VARIABLE symbols RESULT_VARIABLE code ERROR_VARIABLE error)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "check_kernel_objects: ${NM} ${object} failed: ${error}")
  endif()
  string(REPLACE "\n" ";" lines "${symbols}")
  set(entries 0)
  foreach(line IN LISTS lines)
    if(line STREQUAL "")
      continue()
    endif()
    string(REGEX MATCH "^([^ ]+) ([A-Za-z?]) " parsed "${line}")
    set(name "${CMAKE_MATCH_1}")
    set(type "${CMAKE_MATCH_2}")
    if(name MATCHES "^_GLOBAL__sub_I")
      message(FATAL_ERROR "check_kernel_objects: ${object} has a static initialiser (${name}): "
                          "region_kernels.cpp must not construct anything at load")
    endif()
    if(type MATCHES "^[A-Z]$")
      if(type STREQUAL "T" AND name MATCHES "^_ZN15deformable_flsm6detail[0-9]+(rotationBatch|regionBatch|fusedMultiplyAddProbe)V[34]E")
        math(EXPR entries "${entries} + 1")
      else()
        message(FATAL_ERROR "check_kernel_objects: ${object} defines the global symbol ${name} "
                            "(type ${type}); only the kernels' entries may be global: give it "
                            "internal linkage or keep it out of region_kernels.cpp")
      endif()
    elseif(type MATCHES "^[uvVwW]$")
      message(FATAL_ERROR "check_kernel_objects: ${object} defines the weak symbol ${name}")
    endif()
  endforeach()
  if(NOT entries EQUAL 3)
    message(FATAL_ERROR "check_kernel_objects: ${object} has ${entries} kernel entries, not 3")
  endif()
endforeach()
