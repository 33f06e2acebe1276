//! The USB port: a CDC-ACM (virtual serial port) device and its tasks.
//!
//! - [`writer_task`] sends what the device application queued, encoded with
//!   `device::encode_outgoing`, while a host program has the port open (DTR).
//! - [`reader_task`] feeds every received byte into `device::HostInput` and queues the requests.
//! - [`control_task`] tracks DTR.
//! - [`device_task`] runs the USB device itself (enumeration, control requests).

use defmt::{debug, info, warn};
use device::{encode_outgoing, HostInput, MAX_OUTGOING_LEN};
use embassy_stm32::peripherals::USB_OTG_FS;
use embassy_stm32::usb;
use embassy_usb::class::cdc_acm::{CdcAcmClass, ControlChanged, Receiver, Sender, State};
use embassy_usb::driver::EndpointError;
use embassy_usb::{Builder, UsbDevice};
use static_cell::StaticCell;

use crate::board::{Irqs, UsbPeripherals};
use crate::host_port::{self, OUTGOING};

/// pid.codes' test VID:PID pair (vendor 0x1209, product 0x0001), free for private testing only:
/// get a PID of your own (pid.codes allocates them to open-source hardware) before the pad leaves
/// the lab, and change it here and in the defaults of the host tool's `--vid`/`--pid` options.
pub const USB_VENDOR_ID: u16 = 0x1209;
/// See [`USB_VENDOR_ID`].
pub const USB_PRODUCT_ID: u16 = 0x0001;
const USB_MANUFACTURER: &str = "taxel";
const USB_PRODUCT: &str = "taxel pad 2x2";
/// Full-speed bulk endpoints carry at most 64 bytes per packet.
const USB_MAX_PACKET_BYTES: u16 = wire::USB_FULL_SPEED_PACKET_LEN as u16;
/// Bus-powered; the MCU, the FDC1004 and the TMP117 draw well under 100 mA.
const USB_MAX_POWER_MA: u16 = 100;
/// Descriptor and endpoint buffers, sized with margin (embassy checks them at run time).
const ENDPOINT_OUT_BUFFER_BYTES: usize = 256;
const DESCRIPTOR_BUFFER_BYTES: usize = 256;
const CONTROL_BUFFER_BYTES: usize = 64;

/// The USB driver of the Black Pill's OTG FS port.
pub type UsbDriver = usb::Driver<'static, USB_OTG_FS>;

/// The USB device and the three halves of its CDC-ACM class, one per task.
pub struct UsbParts {
    /// The device, for [`device_task`].
    pub device: UsbDevice<'static, UsbDriver>,
    /// The IN endpoint, for [`writer_task`].
    pub sender: Sender<'static, UsbDriver>,
    /// The OUT endpoint, for [`reader_task`].
    pub receiver: Receiver<'static, UsbDriver>,
    /// Line state changes, for [`control_task`].
    pub control: ControlChanged<'static>,
}

/// Builds the USB device; call once (a second call returns `None`).
pub fn build(peripherals: UsbPeripherals) -> Option<UsbParts> {
    static ENDPOINT_OUT_BUFFER: StaticCell<[u8; ENDPOINT_OUT_BUFFER_BYTES]> = StaticCell::new();
    static CONFIG_DESCRIPTOR: StaticCell<[u8; DESCRIPTOR_BUFFER_BYTES]> = StaticCell::new();
    static BOS_DESCRIPTOR: StaticCell<[u8; DESCRIPTOR_BUFFER_BYTES]> = StaticCell::new();
    static CONTROL_BUFFER: StaticCell<[u8; CONTROL_BUFFER_BYTES]> = StaticCell::new();
    static CDC_ACM_STATE: StaticCell<State<'static>> = StaticCell::new();

    let mut driver_config = usb::Config::default();
    // The Black Pill does not route VBUS to PA9 and is powered by the cable it enumerates on, so
    // "VBUS present" is implied by running at all; enabling detection without the pin wired would
    // keep the device from ever connecting. A self-powered variant must wire PA9 and enable it.
    driver_config.vbus_detection = false;
    let driver = usb::Driver::new_fs(
        peripherals.otg_fs,
        Irqs,
        peripherals.d_plus,
        peripherals.d_minus,
        ENDPOINT_OUT_BUFFER.try_init([0; ENDPOINT_OUT_BUFFER_BYTES])?,
        driver_config,
    );

    let mut config = embassy_usb::Config::new(USB_VENDOR_ID, USB_PRODUCT_ID);
    config.manufacturer = Some(USB_MANUFACTURER);
    config.product = Some(USB_PRODUCT);
    config.serial_number = Some(embassy_stm32::uid::uid_hex());
    config.max_power = USB_MAX_POWER_MA;
    config.max_packet_size_0 = USB_MAX_PACKET_BYTES as u8;

    let mut builder = Builder::new(
        driver,
        config,
        CONFIG_DESCRIPTOR.try_init([0; DESCRIPTOR_BUFFER_BYTES])?,
        BOS_DESCRIPTOR.try_init([0; DESCRIPTOR_BUFFER_BYTES])?,
        &mut [],
        CONTROL_BUFFER.try_init([0; CONTROL_BUFFER_BYTES])?,
    );
    let class = CdcAcmClass::new(
        &mut builder,
        CDC_ACM_STATE.try_init(State::new())?,
        USB_MAX_PACKET_BYTES,
    );
    let device = builder.build();
    let (sender, receiver, control) = class.split_with_control();
    Some(UsbParts {
        device,
        sender,
        receiver,
        control,
    })
}

/// Runs the USB device: enumeration, suspend and resume, control requests.
#[embassy_executor::task]
pub async fn device_task(mut device: UsbDevice<'static, UsbDriver>) -> ! {
    device.run().await
}

/// Tracks DTR: a host program opening the port sets it, closing the port (or a bus reset)
/// clears it. Frames queued for a host that left are stale, so they are dropped.
#[embassy_executor::task]
pub async fn control_task(control: ControlChanged<'static>) -> ! {
    loop {
        control.control_changed().await;
        let data_terminal_ready = control.dtr();
        if host_port::set_host_connected(data_terminal_ready) != data_terminal_ready {
            if data_terminal_ready {
                info!("host opened the port (DTR set)");
            } else {
                info!("host closed the port (DTR clear)");
                OUTGOING.clear();
            }
        }
    }
}

/// Sends the device application's frames while DTR is set and drops them otherwise.
///
/// `write_packet` returns once the packet is in the TX FIFO; the next write waits for the host to
/// take the previous one. A host that has the port open but does not read therefore stalls this
/// task, never the acquisition loop: the queue fills up and the device counts the drops. After a
/// close and reopen the host may get the one packet that was waiting; its decoder resynchronises
/// on the next frame delimiter.
#[embassy_executor::task]
pub async fn writer_task(mut sender: Sender<'static, UsbDriver>) -> ! {
    let mut buffer = [0u8; MAX_OUTGOING_LEN];
    loop {
        sender.wait_connection().await;
        info!("USB configured");
        OUTGOING.clear();
        loop {
            let outgoing = OUTGOING.receive().await;
            if !sender.dtr() {
                continue;
            }
            let Some(length) = encode_outgoing(&outgoing, &mut buffer) else {
                warn!("an outgoing frame did not fit the encode buffer");
                continue;
            };
            match write_transfer(&mut sender, &buffer[..length]).await {
                Ok(()) => {}
                Err(EndpointError::Disabled) => {
                    info!("USB disconnected");
                    break;
                }
                Err(EndpointError::BufferOverflow) => {
                    warn!("a packet was larger than the IN endpoint");
                }
            }
        }
    }
}

async fn write_transfer(
    sender: &mut Sender<'static, UsbDriver>,
    bytes: &[u8],
) -> Result<(), EndpointError> {
    // The packets, and the zero-length packet after an exact multiple of 64 bytes, come from
    // the portable rule the host tests check.
    for packet in wire::usb_packets(bytes) {
        sender.write_packet(packet).await?;
    }
    Ok(())
}

/// Turns received bytes into requests and queues them for the acquisition loop; a full queue
/// drops the request (counted, and reported to the host as a refused frame).
#[embassy_executor::task]
pub async fn reader_task(mut receiver: Receiver<'static, UsbDriver>) -> ! {
    let mut packet = [0u8; USB_MAX_PACKET_BYTES as usize];
    loop {
        receiver.wait_connection().await;
        // A partial frame from before a disconnect must not prefix the next one.
        let mut input = HostInput::new();
        loop {
            let length = match receiver.read_packet(&mut packet).await {
                Ok(length) => length,
                Err(EndpointError::Disabled) => break,
                Err(EndpointError::BufferOverflow) => {
                    warn!("a packet was larger than the OUT buffer");
                    continue;
                }
            };
            for &byte in &packet[..length] {
                if let Some(event) = input.push(byte) {
                    if !host_port::push_host_event(event) {
                        warn!("host request dropped: the request queue is full");
                    }
                }
            }
        }
        debug!("USB reader waiting for a connection");
    }
}
