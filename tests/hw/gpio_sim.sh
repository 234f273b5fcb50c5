#!/bin/sh
# The GPIO backends over real libgpiod against the kernel's gpio-sim (configfs): a simulated
# chip with 8 lines; phases of a 4-line, 4-phase, duty-1/4 pattern must light exactly line k
# in phase k (docs/drivers.md, "Illuminator: which line is lit in which phase"), and an
# active-low trigger line must idle high after a pulse.
# Usage: gpio_sim.sh GPIO_SIM_DRIVE. Exit 77 ("skipped: ...") where gpio-sim is unavailable.
set -u
drive=$1
skip() { echo "skipped: $*"; exit 77; }
fail() { echo "FAIL: $*" >&2; exit 1; }

[ "$(id -u)" -eq 0 ] || skip "gpio-sim needs root (configfs and /dev/gpiochip*)"
modprobe gpio-sim 2>/dev/null || true
cfg=/sys/kernel/config
[ -d "$cfg" ] || skip "no $cfg"
[ -d "$cfg/gpio-sim" ] || mount -t configfs none "$cfg" 2>/dev/null || true
[ -d "$cfg/gpio-sim" ] || skip "gpio-sim not available (kernel module gpio-sim, CONFIG_GPIO_SIM)"
sim="$cfg/gpio-sim/descatter-$$"
mkdir "$sim" 2>/dev/null || skip "cannot create $sim"
cleanup() {
  echo 0 >"$sim/live" 2>/dev/null
  rmdir "$sim/bank0" "$sim" 2>/dev/null
}
trap cleanup EXIT
mkdir "$sim/bank0" && echo 8 >"$sim/bank0/num_lines" && echo 1 >"$sim/live" ||
  skip "gpio-sim refused the configuration"
chip=$(cat "$sim/bank0/chip_name")
dev=$(cat "$sim/dev_name")
sysfs="/sys/devices/platform/$dev/$chip"
[ -d "$sysfs" ] || skip "no $sysfs"
[ -e "/dev/$chip" ] || skip "no /dev/$chip"

out=$("$drive" "$chip" 2,3,4,5 4 "$sysfs") || fail "gpio_sim_drive: $out"
echo "$out"
expect="phase 0: 1000
phase 1: 0100
phase 2: 0010
phase 3: 0001
trigger idle: 1"
[ "$out" = "$expect" ] || fail "levels differ from the table:
$expect"
echo "gpio-sim: ok ($chip)"
