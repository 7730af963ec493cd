//! A flag's parser from a library [`Choice`]: the names a flag accepts and `--help` lists are
//! the enum's own, as the parameters and config files spell them, so the command line cannot
//! drift from them. Accepted, refused and listed as clap's `ValueEnum` would (the same
//! "invalid value … [possible values: …]" error).

use std::ffi::OsStr;
use std::marker::PhantomData;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::error::ErrorKind;

use ist_monitor::choice::Choice;

/// The parser of a flag that picks one value of `T` by name; `--help` lists each value with its
/// [`Choice::about`].
#[derive(Clone, Copy)]
pub struct ChoiceParser<T>(PhantomData<fn() -> T>);

/// The parser of a flag that takes one of `T`'s names.
pub fn choice<T: Choice + Send + Sync>() -> ChoiceParser<T> {
    ChoiceParser(PhantomData)
}

impl<T: Choice> ChoiceParser<T> {
    fn values(&self) -> impl Iterator<Item = PossibleValue> + '_ {
        T::ALL.iter().map(|&c| match c.about() {
            "" => PossibleValue::new(c.name()),
            about => PossibleValue::new(c.name()).help(about),
        })
    }
}

impl<T: Choice + Send + Sync> TypedValueParser for ChoiceParser<T> {
    type Value = T;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &OsStr,
    ) -> Result<T, clap::Error> {
        // Not UTF-8: refused as a name that is none of the values, as `ValueEnum`'s parser does.
        let text = value.to_string_lossy();
        let given =
            PossibleValuesParser::new(self.values()).parse_ref(cmd, arg, OsStr::new(&*text))?;
        let ignore_case = arg.is_some_and(clap::Arg::is_ignore_case_set);
        self.values()
            .zip(T::ALL)
            .find(|(v, _)| v.matches(&given, ignore_case))
            .map(|(_, &c)| c)
            .ok_or_else(|| clap::Error::new(ErrorKind::InvalidValue).with_cmd(cmd))
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(self.values()))
    }
}
