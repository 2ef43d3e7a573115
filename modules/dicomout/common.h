// Internal to the dicomout module (DCMTK-facing): what the three writers share.
#pragma once

#include <string>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include "dicomout/dicomout.h"

namespace ms::dicomout {

// DCMTK's own log silenced (once per process): every condition is checked.
void quiet_dcmtk();

// A new UID under DCMTK's site root (dcmGenerateUniqueIdentifier).
std::string new_uid();

// Writes the study context's patient and general study attributes into item,
// replacing what is there, plus the de-identification attributes when set.
void apply_study_context(DcmItem& item, const StudyContext& study);

// The general series and equipment attributes of a MandiSym output series:
// Modality, SeriesInstanceUID (new), SeriesNumber, SeriesDescription,
// Manufacturer "MandiSym", SoftwareVersions, InstanceNumber 1, content and
// instance-creation date/time (now), FrameOfReferenceUID where given.
// Returns the SeriesInstanceUID written.
std::string apply_output_series(DcmItem& item, const StudyContext& study, const DicomSource& source, const std::string& modality,
                                int series_number, const std::string& description);

// Adds the source series and its instances to item's
// ReferencedSeriesSequence (0008,1115) (Common Instance Reference module).
void reference_source_series(DcmItem& item, const DicomSource& source);

// Writes the dataset as a Part 10 file (explicit VR little endian; under
// path.partial, then renamed) and returns what was written; throws
// ms::Error(OutputFailed) naming the path.
Written save(DcmFileFormat& file, const std::string& path, const std::string& what);

// Throws ms::Error(Internal) with context when cond is bad.
void check(const OFCondition& cond, const std::string& context);

}  // namespace ms::dicomout
