# Run by ctest after the discovered cases of gf_gpu_tests are included: gives them the labels
# `backend` and `gpu`. gtest_discover_tests cannot pass a list-valued property (its generated
# script splits "backend;gpu" into LABELS backend plus a property named gpu), so the labels are
# set here on the list the discovery leaves in gf_gpu_tests_TESTS.
if(gf_gpu_tests_TESTS)
  set_tests_properties(${gf_gpu_tests_TESTS} PROPERTIES LABELS "backend;gpu")
endif()
