# Tests: gtest unit tests of the core, build-shape checks, and rostests. Run by `ctest`.

# Core unit tests are held to the same rule as the core: no ROS headers.
function(mvis_core_test name)
  catkin_add_gtest(${name} ${ARGN})
  target_link_libraries(${name} mvis_core gtest_main)
  target_include_directories(${name} BEFORE PRIVATE ${MVIS_ROS_GUARD_DIR})
  target_compile_definitions(${name} PRIVATE MVIS_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
endfunction()

mvis_core_test(test_lie test/unit/test_lie.cpp)
mvis_core_test(test_calibration_status test/unit/test_calibration_status.cpp)
mvis_core_test(test_tag_landmark_manifold test/unit/test_tag_landmark_manifold.cpp)
mvis_core_test(test_rig_io test/unit/test_rig_io.cpp test/unit/test_rig_io_errors.cpp
  test/unit/test_rig_io_formats.cpp)

# A ROS include inside the core must fail to compile, with a message that says why.
add_library(mvis_ros_guard_probe OBJECT EXCLUDE_FROM_ALL test/unit/ros_include_guard_probe.cpp)
target_include_directories(mvis_ros_guard_probe BEFORE PRIVATE ${MVIS_ROS_GUARD_DIR})
target_link_libraries(mvis_ros_guard_probe PRIVATE mvis_core)
add_test(NAME core_rejects_ros_includes
  COMMAND ${CMAKE_COMMAND} --build ${CMAKE_BINARY_DIR} --target mvis_ros_guard_probe)
set_tests_properties(core_rejects_ros_includes PROPERTIES
  PASS_REGULAR_EXPRESSION "mvis_core must not include ROS headers \\(ros/ros.h\\)")

# mvis_core links no ROS library.
add_test(NAME core_links_without_ros
  COMMAND ${CMAKE_COMMAND} -DLIBRARY=$<TARGET_FILE:mvis_core>
          -P ${PROJECT_SOURCE_DIR}/test/unit/check_no_ros_link.cmake)

# The core's layers (doc/architecture.md) are not crossed, and no source file is over 600 lines.
add_test(NAME core_layers
  COMMAND ${CMAKE_COMMAND} -DROOT=${PROJECT_SOURCE_DIR} -P ${PROJECT_SOURCE_DIR}/test/unit/check_layers.cmake)

find_package(rostest REQUIRED)
add_rostest(test/ros/nodelet_loads.test DEPENDENCIES mvis_ros mvis_node)
add_rostest(test/ros/bad_config.test DEPENDENCIES mvis_ros mvis_node)
add_rostest(test/ros/nodelet_compressed.test DEPENDENCIES mvis_ros mvis_node)

mvis_core_test(test_tag_detector test/unit/test_tag_detector.cpp test/unit/board_images.cpp)
mvis_core_test(test_tag_corners test/unit/test_tag_corners.cpp test/unit/board_images.cpp)
mvis_core_test(test_aprilgrid_real test/unit/test_aprilgrid_real.cpp)
mvis_core_test(test_fuzz test/unit/test_fuzz.cpp)
mvis_core_test(test_determinism test/unit/test_determinism.cpp)
mvis_core_test(test_faults test/unit/test_faults.cpp)
mvis_core_test(test_tag_checks test/unit/test_tag_checks.cpp)
mvis_core_test(test_tag_frontend test/unit/test_tag_frontend.cpp)
mvis_core_test(test_predicted_regions test/unit/test_predicted_regions.cpp)
add_rostest(test/ros/tag_detections.test DEPENDENCIES mvis_ros mvis_node)
mvis_core_test(test_camera_model test/unit/test_camera_model.cpp)
mvis_core_test(test_sim_inertial test/unit/test_sim_inertial.cpp)
mvis_core_test(test_sim_rig test/unit/test_sim_rig.cpp)
mvis_core_test(test_simulation_config test/unit/test_simulation_config.cpp)

# ROS-side gtests (bags): link mvis_ros, no include guard.
catkin_add_gtest(test_simulation_bag test/ros/test_simulation_bag.cpp)
target_link_libraries(test_simulation_bag mvis_ros gtest_main)
target_compile_definitions(test_simulation_bag PRIVATE MVIS_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
catkin_add_gtest(test_fuzz_messages test/ros/test_fuzz_messages.cpp)
target_link_libraries(test_fuzz_messages mvis_ros gtest_main)
target_compile_definitions(test_fuzz_messages PRIVATE MVIS_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
catkin_add_gtest(test_offline_inputs test/ros/test_offline_inputs.cpp)
target_link_libraries(test_offline_inputs mvis_ros gtest_main)
target_compile_definitions(test_offline_inputs PRIVATE MVIS_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
catkin_add_gtest(test_nodelet_options test/ros/test_nodelet_options.cpp)
target_link_libraries(test_nodelet_options mvis_ros gtest_main)
target_compile_definitions(test_nodelet_options PRIVATE MVIS_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
catkin_add_gtest(test_real_euroc test/ros/test_real_euroc.cpp)
target_link_libraries(test_real_euroc mvis_ros gtest_main)
target_compile_definitions(test_real_euroc PRIVATE MVIS_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
mvis_core_test(test_imu_factor test/unit/test_imu_factor.cpp)
mvis_core_test(test_aux_factors test/unit/test_aux_factors.cpp)
mvis_core_test(test_tag_reprojection_factor test/unit/test_tag_reprojection_factor.cpp)
mvis_core_test(test_marginalization test/unit/test_marginalization.cpp)
mvis_core_test(test_observability test/unit/test_observability.cpp)
mvis_core_test(test_estimator test/unit/test_estimator.cpp)
mvis_core_test(test_odometry_propagator test/unit/test_odometry_propagator.cpp)
mvis_core_test(test_serial_worker test/unit/test_serial_worker.cpp)
mvis_core_test(test_estimator_sensors test/unit/test_estimator_sensors.cpp)
mvis_core_test(test_estimator_imu_intrinsics test/unit/test_estimator_imu_intrinsics.cpp)
mvis_core_test(test_estimator_degenerate test/unit/test_estimator_degenerate.cpp)
mvis_core_test(test_estimator_changes test/unit/test_estimator_changes.cpp)
# The change test itself, on synthetic evidence (a private part of the estimator).
mvis_core_test(test_change_detector test/unit/test_change_detector.cpp)
target_include_directories(test_change_detector PRIVATE ${PROJECT_SOURCE_DIR}/src/core/estimator)

# A simulated VI-Rig bag for the replay rostest, made at build time: the VI-Rig with a second
# auxiliary IMU (two aux IMUs and a gyroscope).
set(MVIS_REPLAY_DATA ${CMAKE_BINARY_DIR}/test_data/replay)
set(MVIS_REPLAY_RIG ${CMAKE_BINARY_DIR}/test_data/rig_two_aux)
add_custom_command(OUTPUT ${MVIS_REPLAY_DATA}/sim.bag
  COMMAND ${CMAKE_COMMAND} -E remove_directory ${MVIS_REPLAY_DATA}
  COMMAND ${CMAKE_COMMAND} -E copy_directory ${PROJECT_SOURCE_DIR}/config/sim_vi_rig
          ${MVIS_REPLAY_RIG}
  COMMAND ${CMAKE_COMMAND} -E copy ${PROJECT_SOURCE_DIR}/test/ros/two_aux_imu_chain.yaml
          ${MVIS_REPLAY_RIG}/kalibr_imu_chain.yaml
  COMMAND mvis_simulate --rig ${MVIS_REPLAY_RIG}
          --sim ${PROJECT_SOURCE_DIR}/test/ros/replay_sim.yaml --output ${MVIS_REPLAY_DATA}
          --detections
  DEPENDS mvis_simulate ${PROJECT_SOURCE_DIR}/test/ros/replay_sim.yaml
          ${PROJECT_SOURCE_DIR}/test/ros/two_aux_imu_chain.yaml
          ${PROJECT_SOURCE_DIR}/config/sim_vi_rig/kalibr_imucam_chain.yaml)
add_custom_target(mvis_replay_data DEPENDS ${MVIS_REPLAY_DATA}/sim.bag)
add_dependencies(tests mvis_replay_data)
add_rostest(test/ros/replay.test ARGS data:=${MVIS_REPLAY_DATA}
  DEPENDENCIES mvis_ros mvis_node mvis_replay_data)
# The knock rostest's bag: 16 s of the VI-Rig whose cam1 is knocked at 9 s (truth_start/ is the
# calibration before, truth/ after).
set(MVIS_KNOCK_DATA ${CMAKE_BINARY_DIR}/test_data/knock)
add_custom_command(OUTPUT ${MVIS_KNOCK_DATA}/sim.bag
  COMMAND ${CMAKE_COMMAND} -E remove_directory ${MVIS_KNOCK_DATA}
  COMMAND mvis_simulate --rig ${PROJECT_SOURCE_DIR}/config/sim_vi_rig
          --sim ${PROJECT_SOURCE_DIR}/test/ros/knock_sim.yaml --output ${MVIS_KNOCK_DATA}
          --detections
  DEPENDS mvis_simulate ${PROJECT_SOURCE_DIR}/test/ros/knock_sim.yaml)
add_custom_target(mvis_knock_data DEPENDS ${MVIS_KNOCK_DATA}/sim.bag)
add_dependencies(tests mvis_knock_data)
add_rostest(test/ros/knock.test ARGS data:=${MVIS_KNOCK_DATA}
  DEPENDENCIES mvis_ros mvis_node mvis_knock_data)
# The same bag without the board's aprilgrid.yaml: tag corners as landmarks.
set(MVIS_NOBOARD_CONFIG ${CMAKE_BINARY_DIR}/test_data/replay_noboard_config)
add_custom_command(OUTPUT ${MVIS_NOBOARD_CONFIG}/kalibr_imu_chain.yaml
  COMMAND ${CMAKE_COMMAND} -E remove_directory ${MVIS_NOBOARD_CONFIG}
  COMMAND ${CMAKE_COMMAND} -E copy_directory ${MVIS_REPLAY_DATA}/config ${MVIS_NOBOARD_CONFIG}
  COMMAND ${CMAKE_COMMAND} -E remove ${MVIS_NOBOARD_CONFIG}/aprilgrid.yaml
  DEPENDS ${MVIS_REPLAY_DATA}/sim.bag)
add_custom_target(mvis_noboard_config DEPENDS ${MVIS_NOBOARD_CONFIG}/kalibr_imu_chain.yaml)
# The bag's rule is also written into this target (its output is a dependency above): without
# this order both targets could run it at once under make -j (seen when mvis_simulate changed:
# one copy of the rig removed under the other).
add_dependencies(mvis_noboard_config mvis_replay_data)
add_dependencies(tests mvis_noboard_config)
add_rostest(test/ros/replay_noboard.test
  ARGS data:=${MVIS_REPLAY_DATA} config:=${MVIS_NOBOARD_CONFIG}
       result:=${CMAKE_BINARY_DIR}/test_data/replay_noboard_result
  DEPENDENCIES mvis_ros mvis_node mvis_noboard_config)
# The fault rostest's bag: 16 s of the same rig, with a 0.3 s hole in imu0 at 11 s, the bag
# restarted at 13 s with its first 3 s, and garbled and repeated messages (mvis_faults).
set(MVIS_FAULTS_DATA ${CMAKE_BINARY_DIR}/test_data/faults)
add_custom_command(OUTPUT ${MVIS_FAULTS_DATA}/faulted.bag
  COMMAND ${CMAKE_COMMAND} -E remove_directory ${MVIS_FAULTS_DATA}
  COMMAND mvis_simulate --rig ${MVIS_REPLAY_RIG}
          --sim ${PROJECT_SOURCE_DIR}/test/ros/faults_sim.yaml --output ${MVIS_FAULTS_DATA}
          --detections
  COMMAND mvis_faults ${MVIS_FAULTS_DATA}/sim.bag ${MVIS_FAULTS_DATA}/faulted.bag
          gap:/imu0:11:0.3,restart:all:13:3,corrupt:/imu0:2:12:0.01,repeat:all:2:12:0.01,corrupt:/cam1/image_raw/tag_detections:2:12:0.02
  DEPENDS mvis_simulate mvis_faults mvis_replay_data ${PROJECT_SOURCE_DIR}/test/ros/faults_sim.yaml)
add_custom_target(mvis_faults_data DEPENDS ${MVIS_FAULTS_DATA}/faulted.bag)
# After the replay bag's target, which makes the rig directory this one reads.
add_dependencies(mvis_faults_data mvis_replay_data)
add_dependencies(tests mvis_faults_data)
add_rostest(test/ros/faults.test ARGS data:=${MVIS_FAULTS_DATA}
  DEPENDENCIES mvis_ros mvis_node mvis_faults_data)
mvis_core_test(test_initialization test/unit/test_initialization.cpp)
mvis_core_test(test_estimate_log test/unit/test_estimate_log.cpp)
mvis_core_test(test_evaluation test/unit/test_evaluation.cpp)

# Evaluation scripts (scripts/mvis_evaluation.py, scripts/monte_carlo): Python unit tests on
# synthetic inputs with known answers, with Debian's python3 and numpy/matplotlib.
add_test(NAME python_evaluation
  COMMAND /usr/bin/python3 -m unittest discover -s ${PROJECT_SOURCE_DIR}/test/python -v)
mvis_core_test(test_imu_correction test/unit/test_imu_correction.cpp)
mvis_core_test(test_imu_reintegration test/unit/test_imu_reintegration.cpp)
mvis_core_test(test_estimator_landmarks test/unit/test_estimator_landmarks.cpp)
mvis_core_test(test_estimator_batch test/unit/test_estimator_batch.cpp)
mvis_core_test(test_block_covariance test/unit/test_block_covariance.cpp)
target_include_directories(test_block_covariance PRIVATE ${PROJECT_SOURCE_DIR}/src/core/estimator)
# Every YAML file mvis writes, read by PyYAML (YAML 1.1: Kalibr's and ROS's Python tools).
add_test(NAME python_result_yaml
  COMMAND /usr/bin/python3 ${PROJECT_SOURCE_DIR}/test/yaml/check_result_yaml.py
    $<TARGET_FILE:mvis_simulate> $<TARGET_FILE:mvis_offline> ${PROJECT_SOURCE_DIR}/config/sim_small_rig)
# report.md against an independent reading of the same result directory, and --params in effect.
add_test(NAME report_md
  COMMAND /usr/bin/python3 ${PROJECT_SOURCE_DIR}/test/yaml/check_report.py
    $<TARGET_FILE:mvis_simulate> $<TARGET_FILE:mvis_offline> ${PROJECT_SOURCE_DIR}/config/sim_small_rig)
# Guided calibration: ready in time and honest on hand-held motion, never on yaw only, camera
# distortion not converged without the image's corners.
add_test(NAME guided_calibration
  COMMAND /usr/bin/python3 ${PROJECT_SOURCE_DIR}/test/guided/check_guided.py
    $<TARGET_FILE:mvis_simulate> $<TARGET_FILE:mvis_offline> ${PROJECT_SOURCE_DIR}/config/sim_vi_rig)
# The same bytes out whatever the number of image threads.
add_test(NAME offline_image_threads
  COMMAND ${PROJECT_SOURCE_DIR}/test/tools/offline_threads_same.sh
    $<TARGET_FILE:mvis_simulate> $<TARGET_FILE:mvis_offline> ${PROJECT_SOURCE_DIR}/config/sim_small_rig)
# mvis_offline --params with an unknown key: refused at start (exit 2), naming the file and key.
add_test(NAME offline_params_refused
  COMMAND ${PROJECT_SOURCE_DIR}/test/tools/offline_params_refused.sh $<TARGET_FILE:mvis_offline>)
# mvis_offline --help: the usage on standard output, exit status 0.
add_test(NAME offline_help
  COMMAND /bin/bash -c "set -o pipefail; '$<TARGET_FILE:mvis_offline>' --help | grep '^usage: mvis_offline'")
