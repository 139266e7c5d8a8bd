# mvis_make_ros_include_guard(OUT_DIR_VAR)
#
# Writes a directory of guard headers, one for every header of the ROS packages found on this
# machine (and for mvis's own generated messages), each holding only an #error. Put first on a
# target's include path, it turns any ROS include in that target into a compile error that says
# why. Debian keeps ROS headers in /usr/include, so this is what keeps the core free of ROS.
set(MVIS_ROS_HEADER_DIRS
  ros rosbag rosconsole roscpp rostime nodelet pluginlib class_loader tf tf2 tf2_ros tf2_msgs
  cv_bridge image_transport sensor_msgs nav_msgs geometry_msgs std_msgs std_srvs
  diagnostic_msgs diagnostic_updater message_filters visualization_msgs xmlrpcpp rostest
  actionlib dynamic_reconfigure)

function(mvis_make_ros_include_guard out_var)
  set(guard_dir ${CMAKE_BINARY_DIR}/ros_include_guard)
  set(headers)
  foreach(dir ${MVIS_ROS_HEADER_DIRS})
    if(IS_DIRECTORY /usr/include/${dir})
      file(GLOB_RECURSE found RELATIVE /usr/include /usr/include/${dir}/*.h /usr/include/${dir}/*.hpp)
      list(APPEND headers ${found})
    endif()
  endforeach()
  file(GLOB msg_files RELATIVE ${PROJECT_SOURCE_DIR}/msg ${PROJECT_SOURCE_DIR}/msg/*.msg)
  foreach(msg ${msg_files})
    string(REGEX REPLACE "\\.msg$" ".h" header "mvis/${msg}")
    list(APPEND headers ${header})
  endforeach()
  foreach(header ${headers})
    set(text "#error \"mvis_core must not include ROS headers (${header}); ROS belongs in src/ros\"\n")
    set(path ${guard_dir}/${header})
    if(NOT EXISTS ${path})
      file(WRITE ${path} "${text}")
    endif()
  endforeach()
  set(${out_var} ${guard_dir} PARENT_SCOPE)
endfunction()
