# One fuzz smoke run: fresh scratch corpus, then the fuzzer over scratch + seeds + regressions.
file(REMOVE_RECURSE ${SCRATCH})
file(MAKE_DIRECTORY ${SCRATCH})
set(dirs ${SCRATCH})
foreach(d ${CORPUS} ${REGRESS})
    if(IS_DIRECTORY ${d})
        list(APPEND dirs ${d})
    endif()
endforeach()
execute_process(COMMAND ${FUZZER} -max_total_time=${SECONDS} -timeout=10 -rss_limit_mb=1024
                        -malloc_limit_mb=1024 -print_final_stats=1 ${dirs}
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${FUZZER} failed (exit ${rc})")
endif()
