# Every kind of OpenCL program raykit builds, compiled by a second front end. NVIDIA's compiler
# (CUDA 13 on an H200) rejected programs PoCL had always accepted: in OpenCL C 2.0 and later an
# unqualified pointer is generic, but an array parameter (`const float a[3]`) stays private,
# and passing a generic pointer to it is an error. clang's OpenCL C 2.0 front end gives the same
# error, so this test catches it without a GPU. It runs device tests that build the trace,
# packet, scene, hook, refit, build, skinning and renderer programs with RAYKIT_TEST_CL_SOURCES
# set (tests/test_device_support.hpp writes each program's text there), then compiles every
# program with clang at OpenCL C 1.2 and 2.0 (syntax and types only; the -D options kept).
#   cmake -DCLANG=... -DOUT=dir -DRUNS="exe|gtest filter^..." -DMIN_PROGRAMS=N -P cl_programs_check.cmake
string(REPLACE "^" ";" RUNS "${RUNS}")
set(skipped FALSE)
file(REMOVE_RECURSE "${OUT}")
file(MAKE_DIRECTORY "${OUT}")
foreach(run IN LISTS RUNS)
    string(REPLACE "|" ";" run "${run}")
    list(GET run 0 exe)
    list(GET run 1 filter)
    execute_process(COMMAND ${CMAKE_COMMAND} -E env RAYKIT_TEST_CL_SOURCES=${OUT} ${exe} --gtest_filter=${filter}
                            --gtest_brief=1
                    RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
    if(NOT rc EQUAL 0)
        message(FATAL_ERROR "${exe} --gtest_filter=${filter} failed (${rc}):\n${out}")
    endif()
    if(out MATCHES "SKIPPED")
        set(skipped TRUE)
    endif()
endforeach()
file(GLOB sources "${OUT}/*.cl")
list(LENGTH sources count)
if(count EQUAL 0 AND skipped)
    message("raykit: no OpenCL device, so no program was built")
    return()
endif()
if(count LESS MIN_PROGRAMS)
    message(FATAL_ERROR "only ${count} programs were written to ${OUT}, expected at least ${MIN_PROGRAMS}")
endif()
set(failed 0)
foreach(src IN LISTS sources)
    file(STRINGS "${src}" first LIMIT_COUNT 1)
    string(REGEX MATCHALL "-D[^ ]+" defines "${first}")
    foreach(std CL1.2 CL2.0)
        execute_process(COMMAND ${CLANG} -x cl -cl-std=${std} -fsyntax-only -Xclang -finclude-default-header
                                -target spir64 ${defines} "${src}"
                        RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
        if(NOT rc EQUAL 0)
            math(EXPR failed "${failed} + 1")
            message(SEND_ERROR "${src} as OpenCL C ${std}:\n${out}")
        endif()
    endforeach()
endforeach()
if(failed GREATER 0)
    message(FATAL_ERROR "${failed} of ${count} programs x 2 standards did not compile")
endif()
message("raykit: ${count} programs compiled as OpenCL C 1.2 and 2.0 by ${CLANG}")
