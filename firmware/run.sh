#!/usr/bin/env bash
# Builds the firmware and runs it on QEMU's mps2-an386 (Cortex-M4F) with -icount shift=0 (one
# instruction per virtual nanosecond, so the firmware's SysTick counts instructions), decoding
# its defmt log with defmt-print. Exits with the firmware's semihosting exit status.
#
#   firmware/run.sh            build, run, print the log
#   firmware/run.sh --bin seven-joints
#                              the same for the 7-joint compensation binary (src/bin/)
#   firmware/run.sh --size     also print the footprint (flash = .vector_table + .text + .rodata,
#                              the parameter blocks in .calib_slots and the job's measurements
#                              and expected outcomes in .calib_data apart, RAM = .data + .bss;
#                              the peak stack is in the log)
set -euo pipefail
cd "$(dirname "$0")"
size=false
bin=calib-firmware
while [[ $# -gt 0 ]]; do
    case "$1" in
        --size) size=true ;;
        --bin) bin="$2"; shift ;;
        *) echo "usage: run.sh [--size] [--bin NAME]" >&2; exit 2 ;;
    esac
    shift
done
cargo build --release --quiet
elf=target/thumbv7em-none-eabihf/release/$bin
if $size; then
    arm-none-eabi-size -A "$elf" | awk '
        $1 == ".vector_table" || $1 == ".text" || $1 == ".rodata" { flash += $2 }
        $1 == ".data" || $1 == ".bss" { ram += $2 }
        $1 == ".calib_slots" { slots += $2 }
        $1 == ".calib_data" { data += $2 }
        END { printf "flash (vector table + text + rodata): %d bytes\nparameter region (.calib_slots: the embedded blocks): %d bytes\njob data (.calib_data: the measurements and expected outcomes): %d bytes\nstatic RAM (data + bss): %d bytes\n", flash, slots, data, ram }'
fi
set +e
timeout 900 qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic \
    -semihosting-config enable=on,target=native -icount shift=0 -kernel "$elf" \
    | defmt-print -e "$elf"
status=${PIPESTATUS[0]}
echo "firmware exit status: $status"
exit "$status"
