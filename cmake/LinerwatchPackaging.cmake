# Installation layout and the Debian packages (CPack DEB). docs/deploy.md.
#
#   cmake --build --preset default --target package    -> build/linerwatch-{gateway,server,tools}_*.deb
#   scripts/package                                    -> the same plus the firmware image, in out/package/
#
# Three components, one package each:
#   gateway  linerwatch-gateway, its man page, systemd unit, /etc/linerwatch/gateway.json, docs
#   server   linerwatch-server, the dashboard, its man page, unit, /etc/linerwatch/server.json, docs;
#            linerwatch-backup, its service and daily timer, /etc/linerwatch/backup.json
#   tools    linerwatch (diagnose, reconstruct, dem), linerwatch-sim, their man pages
# The units are templates (packaging/systemd/*.service.in) filled in at install time with the
# prefix being installed to: /usr in the packages, /usr/local for `cmake --install build`.
include(GNUInstallDirs)

set(LW_PACKAGING_DIR ${PROJECT_SOURCE_DIR}/packaging)

# ---- man pages, made from each program's --help by help2man ---------------------------------
find_program(LW_HELP2MAN help2man)
set(LW_MAN_DIR ${CMAKE_BINARY_DIR}/man)
function(lw_man_page target component description)
  if(NOT TARGET ${target})
    return()
  endif()
  if(NOT LW_HELP2MAN)
    return()
  endif()
  set(page ${LW_MAN_DIR}/${target}.1)
  set(program $<TARGET_FILE:${target}>)
  if(CMAKE_CROSSCOMPILING_EMULATOR)
    # A cross-built program runs on the build machine through its emulator (qemu-user).
    string(JOIN " " emulator ${CMAKE_CROSSCOMPILING_EMULATOR})
    set(program ${CMAKE_BINARY_DIR}/emulated/${target})
    file(GENERATE OUTPUT ${program} CONTENT "#!/bin/sh\nexec ${emulator} $<TARGET_FILE:${target}> \"$@\"\n"
         FILE_PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE WORLD_READ WORLD_EXECUTE)
  endif()
  add_custom_command(OUTPUT ${page}.gz
    COMMAND ${CMAKE_COMMAND} -E make_directory ${LW_MAN_DIR}
    COMMAND ${LW_HELP2MAN} --no-info --no-discard-stderr --section=1
            --version-string=${PROJECT_VERSION} --name=${description}
            --output=${page} ${program}
    COMMAND gzip -9nf ${page}
    DEPENDS ${target}
    COMMENT "Man page of ${target} (help2man)"
    VERBATIM)
  add_custom_target(lw_man_${target} ALL DEPENDS ${page}.gz)
  install(FILES ${page}.gz DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT ${component})
endfunction()
if(NOT LW_HELP2MAN)
  message(WARNING "help2man not found: no man pages are built or packaged (scripts/install-deps installs it)")
endif()
lw_man_page(linerwatch-gateway gateway "XBee coordinator serial port to MQTT with a durable spool")
lw_man_page(linerwatch-server server "crusher liner wear readings to SQLite, live wear, forecasts, REST and dashboard")
lw_man_page(linerwatch-backup server "online, checked copy of the linerwatch-server database, keeping N")
lw_man_page(linerwatch tools "crusher liner wear: diagnose, reconstruct, DEM wear maps")
lw_man_page(linerwatch-sim tools "crusher liner wear campaign generator and virtual sensor site")

# ---- systemd units (filled in at install time), configuration, docs, examples ------------------
function(lw_install_unit name component)
  set(src ${LW_PACKAGING_DIR}/systemd/${name}.service.in)
  install(CODE "
    set(LW_BINDIR \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_BINDIR}\")
    set(LW_DATADIR \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_DATADIR}\")
    set(LW_DOCDIR \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_DATADIR}/doc\")
    set(unit \"\$ENV{DESTDIR}\${CMAKE_INSTALL_PREFIX}/lib/systemd/system/${name}.service\")
    message(STATUS \"Installing: \${unit}\")
    configure_file(\"${src}\" \"\${unit}\" @ONLY)
    file(CHMOD \"\${unit}\" PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ)
  " COMPONENT ${component})
endfunction()

# /etc/linerwatch/NAME.json: in the package always (a conffile); by `cmake --install` only when
# the file is not there yet (an operator's configuration is never overwritten).
function(lw_install_config file component)
  install(CODE "
    set(dest \"\$ENV{DESTDIR}/etc/linerwatch/${file}\")
    if(EXISTS \"\${dest}\" AND \"\$ENV{DESTDIR}\" STREQUAL \"\")
      message(STATUS \"Keeping: \${dest} (already there)\")
    else()
      message(STATUS \"Installing: \${dest}\")
      file(INSTALL \"${LW_PACKAGING_DIR}/etc/${file}\" DESTINATION \"/etc/linerwatch\"
           PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ)
    endif()
  " COMPONENT ${component})
endfunction()

if(TARGET linerwatch-gateway)
  lw_install_unit(linerwatch-gateway gateway)
  lw_install_config(gateway.json gateway)
  set(doc ${CMAKE_INSTALL_DATADIR}/doc/linerwatch-gateway)
  install(FILES ${PROJECT_SOURCE_DIR}/docs/gateway.md ${PROJECT_SOURCE_DIR}/docs/mqtt.md
                ${PROJECT_SOURCE_DIR}/docs/deploy.md ${PROJECT_SOURCE_DIR}/docs/security.md
          DESTINATION ${doc} COMPONENT gateway)
  install(FILES ${LW_PACKAGING_DIR}/mosquitto/linerwatch.acl ${LW_PACKAGING_DIR}/mosquitto/site-bridge.conf
                ${LW_PACKAGING_DIR}/mosquitto/single-site.conf
          DESTINATION ${doc}/examples/mosquitto COMPONENT gateway)
endif()
if(TARGET linerwatch-server)
  lw_install_unit(linerwatch-server server)
  lw_install_config(server.json server)
  if(TARGET linerwatch-backup)
    lw_install_unit(linerwatch-backup server)
    install(FILES ${LW_PACKAGING_DIR}/systemd/linerwatch-backup.timer DESTINATION lib/systemd/system COMPONENT server)
    lw_install_config(backup.json server)
  endif()
  install(DIRECTORY DESTINATION /etc/linerwatch/crushers COMPONENT server)
  set(doc ${CMAKE_INSTALL_DATADIR}/doc/linerwatch-server)
  install(FILES ${PROJECT_SOURCE_DIR}/docs/server.md ${PROJECT_SOURCE_DIR}/docs/dashboard.md
                ${PROJECT_SOURCE_DIR}/docs/mqtt.md ${PROJECT_SOURCE_DIR}/docs/bundle.md
                ${PROJECT_SOURCE_DIR}/docs/deploy.md ${PROJECT_SOURCE_DIR}/docs/security.md
          DESTINATION ${doc} COMPONENT server)
  install(FILES ${LW_PACKAGING_DIR}/mosquitto/linerwatch.acl ${LW_PACKAGING_DIR}/mosquitto/central.conf
                ${LW_PACKAGING_DIR}/mosquitto/single-site.conf
          DESTINATION ${doc}/examples/mosquitto COMPONENT server)
  install(PROGRAMS ${LW_PACKAGING_DIR}/mosquitto/make-certs
          DESTINATION ${doc}/examples/mosquitto COMPONENT server)
  # The Grafana dashboard of the server's and the gateways' metrics (docs/deploy.md, Metrics and Grafana).
  install(FILES ${LW_PACKAGING_DIR}/grafana/linerwatch.json DESTINATION ${doc}/examples/grafana COMPONENT server)
endif()
if(TARGET linerwatch)
  set(doc ${CMAKE_INSTALL_DATADIR}/doc/linerwatch-tools)
  install(FILES ${PROJECT_SOURCE_DIR}/docs/diagnosis.md ${PROJECT_SOURCE_DIR}/docs/dem.md
                ${PROJECT_SOURCE_DIR}/docs/sim.md ${PROJECT_SOURCE_DIR}/docs/bundle.md
          DESTINATION ${doc} COMPONENT tools)
endif()

# ---- CPack: one .deb per component ------------------------------------------------------------
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME linerwatch)
set(CPACK_PACKAGE_VENDOR "linerwatch")
set(CPACK_PACKAGE_CONTACT "linerwatch maintainers <linerwatch@localhost>")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_INSTALL_PREFIX /usr)
# DESTDIR staging: the units are filled in with /usr (not the staging folder), and /etc works.
set(CPACK_SET_DESTDIR ON)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEB_COMPONENT_INSTALL ON)
if(LW_GATEWAY_ONLY)
  set(CPACK_COMPONENTS_ALL gateway)  # the arm64 build: the site gateway's package alone
else()
  set(CPACK_COMPONENTS_ALL gateway server tools)
endif()
if(LW_DEB_ARCHITECTURE)
  # A cross build's packages are for the target (dpkg --print-architecture names the build machine).
  set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${LW_DEB_ARCHITECTURE})
endif()
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION misc)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_RELEASE 1)
set(CPACK_DEBIAN_PACKAGE_HOMEPAGE "https://localhost/linerwatch")
# Shared-library dependencies from dpkg-shlibdeps (libpaho-mqttpp3-1, libsqlite3-0, libssl3, ...).
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_ENABLE_COMPONENT_DEPENDS OFF)

set(CPACK_DEBIAN_GATEWAY_PACKAGE_NAME linerwatch-gateway)
set(CPACK_DEBIAN_GATEWAY_PACKAGE_DEPENDS "adduser")
set(CPACK_DEBIAN_GATEWAY_PACKAGE_SUGGESTS "mosquitto, mosquitto-clients")
set(CPACK_COMPONENT_GATEWAY_DESCRIPTION "linerwatch site gateway: XBee coordinator serial port to MQTT
 The gateway reads the wear sensors' readings from an XBee coordinator's serial port, keeps every
 record in a durable SQLite spool and publishes it over MQTT until the linerwatch server confirms
 it. Runs as the system user linerwatch-gateway (systemd unit, configuration in
 /etc/linerwatch/gateway.json, spool in /var/lib/linerwatch/gateway/).")
set(CPACK_DEBIAN_SERVER_PACKAGE_NAME linerwatch-server)
set(CPACK_DEBIAN_SERVER_PACKAGE_DEPENDS "adduser")
set(CPACK_DEBIAN_SERVER_PACKAGE_RECOMMENDS "mosquitto, sqlite3")
set(CPACK_DEBIAN_SERVER_PACKAGE_SUGGESTS "linerwatch-tools, mosquitto-clients")
set(CPACK_COMPONENT_SERVER_DESCRIPTION "linerwatch server: liner wear readings, live wear, forecasts, dashboard
 The server stores the readings the site gateways publish over MQTT exactly once in SQLite, scales
 each crusher's DEM wear map into live global wear, forecasts relining dates and serves a REST API
 and a web dashboard. Runs as the system user linerwatch-server (systemd unit, configuration in
 /etc/linerwatch/server.json and /etc/linerwatch/crushers/, database in /var/lib/linerwatch/server/).")
set(CPACK_DEBIAN_TOOLS_PACKAGE_NAME linerwatch-tools)
set(CPACK_DEBIAN_TOOLS_PACKAGE_SUGGESTS "liggghts, openmpi-bin")
set(CPACK_COMPONENT_TOOLS_DESCRIPTION "linerwatch tools: diagnosis, reconstruction, DEM runs, simulator
 linerwatch diagnose, reconstruct and dem (LIGGGHTS wear maps from a crusher's chamber; needs the
 liggghts and openmpi-bin packages), and linerwatch-sim (campaign generator and a virtual sensor
 site for testing a gateway).")

# Maintainer scripts: system user, state directory, configuration mode, systemd, purge.
#   lw_maintainer_scripts(component pkg user state role extra_groups
#                         CONFS file.json... UNITS unit... [POSTINST text] [POSTRM text])
# CONFS: the conffiles in /etc/linerwatch/ (group-readable by the user: they may hold passwords);
# UNITS: enabled and started at install, stopped at removal (a service, or the timer of one).
set(LW_DEB_DIR ${CMAKE_BINARY_DIR}/packaging/debian)
function(lw_maintainer_scripts component pkg user state role extra_groups)
  cmake_parse_arguments(PARSE_ARGV 6 M "" "POSTINST;POSTRM" "CONFS;UNITS")
  set(LW_PKG ${pkg})
  set(LW_USER ${user})
  set(LW_STATE ${state})
  set(LW_ROLE ${role})
  string(JOIN " " LW_CONFS ${M_CONFS})
  string(JOIN " " LW_UNITS ${M_UNITS})
  set(LW_EXTRA_GROUPS "${extra_groups}")
  set(LW_EXTRA_POSTINST "${M_POSTINST}")
  set(LW_EXTRA_POSTRM "${M_POSTRM}")
  set(dir ${LW_DEB_DIR}/${component})
  foreach(script postinst prerm postrm)
    configure_file(${LW_PACKAGING_DIR}/debian/${script}.in ${dir}/${script} @ONLY
                   FILE_PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE
                                    WORLD_READ WORLD_EXECUTE)
  endforeach()
  list(TRANSFORM M_CONFS PREPEND "/etc/linerwatch/")
  string(JOIN "\n" conffiles ${M_CONFS})
  file(WRITE ${dir}/conffiles "${conffiles}\n")
  string(TOUPPER ${component} up)
  set(CPACK_DEBIAN_${up}_PACKAGE_CONTROL_EXTRA ${dir}/postinst ${dir}/prerm ${dir}/postrm ${dir}/conffiles
      PARENT_SCOPE)
  set(CPACK_DEBIAN_${up}_PACKAGE_CONTROL_STRICT_PERMISSION ON PARENT_SCOPE)
endfunction()
lw_maintainer_scripts(gateway linerwatch-gateway linerwatch-gateway gateway gateway dialout
  CONFS gateway.json UNITS linerwatch-gateway.service)
lw_maintainer_scripts(server linerwatch-server linerwatch-server server server ""
  CONFS server.json backup.json
  UNITS linerwatch-server.service linerwatch-backup.timer
  POSTINST "  install -d -m 0755 /etc/linerwatch/crushers
  # The daily backups' folder (backup.json's \"dir\"), the server user's: linerwatch-backup.timer.
  install -d -m 0750 -o \"$user\" -g \"$user\" /var/backups/linerwatch"
  POSTRM "  # The crusher folders (crusher.json, wear maps) and the token file are configuration too:
  # save the wear maps first (docs/deploy.md). The backups in /var/backups/linerwatch stay, like
  # the database; the folder goes when it holds none.
  rm -rf /etc/linerwatch/crushers
  rm -f /etc/linerwatch/tokens.json
  rmdir /var/backups/linerwatch 2>/dev/null || true")

include(CPack)
