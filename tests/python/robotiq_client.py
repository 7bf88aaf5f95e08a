"""An independent Modbus RTU client (minimalmodbus + pyserial) driving the
emulated Robotiq gripper as the Robotiq manual says: activate (reset, then
rACT = 1, wait for gSTA = 3), close at full speed and force (FC16), open
(rPR = 0 by FC6), reading the status with FC3 and FC4. Prints what it read
as JSON for tests/emulate_robotiq.rs to check against the register map.

    robotiq_client.py PORT
"""

import json
import sys
import time

import minimalmodbus
import serial

REQUEST, STATUS = 0x03E8, 0x07D0


def status(gripper, functioncode=3):
    return gripper.read_registers(STATUS, 3, functioncode=functioncode)


def wait_until(gripper, done, functioncode=3, timeout_s=5.0):
    seen = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        regs = status(gripper, functioncode)
        if not seen or seen[-1] != regs:
            seen.append(regs)
        if done(regs):
            return seen
        time.sleep(0.02)
    raise SystemExit(f"timed out; statuses seen: {seen}")


def main(port):
    gripper = minimalmodbus.Instrument(port, 9, mode=minimalmodbus.MODE_RTU)
    gripper.serial.baudrate = 115200
    gripper.serial.bytesize = 8
    gripper.serial.parity = serial.PARITY_NONE
    gripper.serial.stopbits = 1
    gripper.serial.timeout = 0.3
    gripper.clear_buffers_before_each_transaction = True

    gripper.write_registers(REQUEST, [0x0000, 0x0000, 0x0000])  # reset
    gripper.write_registers(REQUEST, [0x0100, 0x0000, 0x0000])  # rACT = 1
    activating = wait_until(gripper, lambda r: (r[0] >> 12) & 0x3 == 3)

    gripper.write_registers(REQUEST, [0x0900, 0x00FF, 0xFFFF])  # close, full speed and force
    closing = wait_until(gripper, lambda r: (r[0] >> 14) != 0)

    gripper.write_register(REQUEST + 1, 0x0000, functioncode=6)  # rPR = 0: open
    opening = wait_until(gripper, lambda r: (r[0] >> 14) == 3 and (r[2] >> 8) == 0, functioncode=4)

    try:
        gripper.read_registers(0x0000, 3)
        bad_address = "answered"
    except minimalmodbus.NoResponseError:
        bad_address = "no response"
    except minimalmodbus.IllegalRequestError:
        bad_address = "exception"

    echo = gripper.read_registers(REQUEST, 3)
    print(json.dumps({
        "activating": activating,
        "closing": closing,
        "opening": opening,
        "request_echo": echo,
        "bad_address": bad_address,
    }))


if __name__ == "__main__":
    main(sys.argv[1])
