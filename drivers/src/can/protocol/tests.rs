//! The legacy layout's ids and frames.

use super::*;

fn layout(taxels: u16) -> XelaCanLayout {
    XelaCanLayout { taxels, ..XelaCanLayout::default() }
}

#[test]
fn the_start_command_and_ids_follow_the_xela_layout() {
    let l = XelaCanLayout::default();
    let start = l.start_command();
    assert_eq!((start.id, start.data()), (0x201, &[7u8, 0][..]));
    let f = l.taxel_frame(3, [0x1234, 0x5678, 0x9ABC], true);
    assert_eq!(f.id, 0x713);
    assert_eq!(f.data(), &[0, 0x12, 0x34, 0x56, 0x78, 0x9A, 0xBC, 0]);
    assert_eq!(l.taxel_of(&f), Some(3));
    assert_eq!(l.taxel_of(&CanFrame::standard(0x720, &[0; 8]).unwrap()), None, "beyond 16 taxels");
    assert_eq!(l.taxel_of(&CanFrame::new(0x713, true, &[0; 8]).unwrap()), None, "extended id");
    assert!(XelaCanLayout { taxel_base_id: 0x7F8, ..l }.validate().is_err());
    assert!(XelaCanLayout { start_base_id: 0x800, ..l }.validate().is_err());
    assert!(layout(0).validate().is_err());
    assert!(CanFrame::standard(0x800, &[]).is_none() && CanFrame::standard(1, &[0; 9]).is_none());
}
