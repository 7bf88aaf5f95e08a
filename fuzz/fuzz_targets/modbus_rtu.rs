//! Arbitrary bytes as a Modbus RTU response to each request the Robotiq
//! driver sends, and as a request to the emulated gripper: no panic; a
//! response the client accepts is exactly the frame the server would encode
//! (right device, function, length and CRC), so that no corrupted reply
//! ever reaches the driver as registers.

#![no_main]

use libfuzzer_sys::fuzz_target;
use slidetrack_drivers::robotiq::modbus::{Request, Response, request_len, response_len};

fuzz_target!(|data: &[u8]| {
    let _ = request_len(data);
    if let Ok((id, request)) = Request::decode(data) {
        assert_eq!(request.encode(id), data, "a decoded request encodes to its bytes");
    }
    let requests = [
        Request::ReadHolding { address: 0x07D0, count: 3 },
        Request::WriteMultiple { address: 0x03E8, values: vec![0x0900, 0x00FF, 0xFFFF] },
        Request::ReadWriteMultiple { read_address: 0x07D0, read_count: 3, write_address: 0x03E8, values: vec![0; 3] },
    ];
    for request in &requests {
        if let Some(len) = response_len(data, request) {
            assert!(len >= 5);
        }
        if let Ok(response) = Response::decode(data, 9, request) {
            assert_eq!(response.encode(9, request.function()), data);
        }
    }
});
