//! A message on its way from one side of the loop to the other: as the frame a link carries,
//! or, where both sides run in one process, as the message itself. Encoding a message only to
//! decode it again a moment later is a quarter of the one-process loop's time; a transport in
//! memory hands the message over and encodes it only for its recording.

use super::{Message, MessageError};
use crate::can::CanFrame;

/// One message on its way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Carried {
    /// A frame as it is: from a link or a recording, or one made malformed on purpose. The
    /// receiving side decodes it.
    Frame(CanFrame),
    /// A message whose fields fit its frame.
    Message(Checked),
}

/// A message whose fields fit its frame: made by [`Carried::checked`] only, so the receiving
/// side reads it without checking it again.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Checked(Message);

impl Checked {
    /// The message.
    #[must_use]
    pub fn message(&self) -> &Message {
        &self.0
    }
}

impl Carried {
    /// `message`, once its fields are checked as [`Message::encode`] checks them: the error a
    /// sender gets is the one encoding would give.
    ///
    /// # Errors
    /// [`MessageError::OutOfRange`] for a field that does not fit its signal.
    pub fn checked(message: Message) -> Result<Carried, MessageError> {
        message.check()?;
        Ok(Carried::Message(Checked(message)))
    }

    /// The frame a link sends.
    ///
    /// # Errors
    /// As [`Message::encode`].
    pub fn frame(&self) -> Result<CanFrame, MessageError> {
        match self {
            Carried::Frame(frame) => Ok(*frame),
            Carried::Message(checked) => checked.0.encode(),
        }
    }

    /// The message as the receiving side reads it: a frame decoded, a message as it is (the
    /// same as decoding its frame, which a property test holds).
    ///
    /// # Errors
    /// As [`Message::decode`].
    pub fn message(&self) -> Result<Message, MessageError> {
        match self {
            Carried::Frame(frame) => Message::decode(frame),
            Carried::Message(checked) => Ok(checked.0),
        }
    }
}

impl From<CanFrame> for Carried {
    fn from(frame: CanFrame) -> Carried {
        Carried::Frame(frame)
    }
}

impl From<&CanFrame> for Carried {
    fn from(frame: &CanFrame) -> Carried {
        Carried::Frame(*frame)
    }
}
