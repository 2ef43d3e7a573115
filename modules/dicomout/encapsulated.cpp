// report.pdf as an Encapsulated PDF Storage object in the source study.
//
// The attributes are set directly rather than through DCMTK's
// DcmEncapsulatedDocument (dcmdata/dcencdoc.h): in 3.6.7 that class is the
// engine of the pdf2dcm/cda2dcm/stl2dcm tools, configured through their
// OFCommandLine options and reading patient and study data from a file of its
// own; setting some twenty attributes is shorter than driving it.
//
// The CT is referenced through the Source Instance Sequence (0042,0013) of
// the Encapsulated Document module. The Encapsulated PDF IOD has no Common
// Instance Reference module: a Referenced Series Sequence (as the SEG and SR
// carry) would make it a Standard Extended SOP Class (dciodvfy warns).
#include <fstream>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"
#include "dicomout/common.h"

namespace ms::dicomout {

namespace {

// The whole file, checked to be a PDF.
std::vector<Uint8> read_pdf(const std::string& pdf_path) {
  std::ifstream in(pdf_path, std::ios::binary);
  if (!in) throw Error(ExitCode::OutputFailed, pdf_path + ": cannot read the PDF report to encapsulate it");
  std::vector<Uint8> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() < 5 || std::string(bytes.begin(), bytes.begin() + 5) != "%PDF-")
    throw Error(ExitCode::Internal, pdf_path + ": not a PDF file, not encapsulated");
  return bytes;
}

// Source Instance Sequence (0042,0013): every CT instance the report was derived from.
void add_source_instances(DcmItem& ds, const DicomSource& source) {
  std::string last;
  for (const DicomSourceFrame& f : source.frames) {
    if (f.sop_instance_uid == last) continue;  // the frames of one multi-frame file
    last = f.sop_instance_uid;
    DcmItem* item = nullptr;
    check(ds.findOrCreateSequenceItem(DCM_SourceInstanceSequence, item, -2), "SourceInstanceSequence");
    check(item->putAndInsertString(DCM_ReferencedSOPClassUID, source.sop_class_uid.c_str()), "ReferencedSOPClassUID");
    check(item->putAndInsertString(DCM_ReferencedSOPInstanceUID, f.sop_instance_uid.c_str()), "ReferencedSOPInstanceUID");
  }
}

// Encapsulated Document module: title, concept name, MIME type, the document (OB, even length) and its length.
void add_document(DcmItem& ds, std::vector<Uint8> pdf) {
  check(ds.putAndInsertString(DCM_BurnedInAnnotation, "YES"), "BurnedInAnnotation");
  check(ds.putAndInsertString(DCM_DocumentTitle, "MandiSym mandibular asymmetry report"), "DocumentTitle");
  DcmItem* concept = nullptr;
  check(ds.findOrCreateSequenceItem(DCM_ConceptNameCodeSequence, concept, -2), "ConceptNameCodeSequence");
  check(concept->putAndInsertString(DCM_CodeValue, "18748-4"), "CodeValue");
  check(concept->putAndInsertString(DCM_CodingSchemeDesignator, "LN"), "CodingSchemeDesignator");
  check(concept->putAndInsertString(DCM_CodeMeaning, "Diagnostic Imaging Report"), "CodeMeaning");
  check(ds.putAndInsertString(DCM_AcquisitionDateTime, ""), "AcquisitionDateTime");
  check(ds.putAndInsertString(DCM_MIMETypeOfEncapsulatedDocument, "application/pdf"), "MIMETypeOfEncapsulatedDocument");
  check(ds.putAndInsertUint32(DCM_EncapsulatedDocumentLength, static_cast<Uint32>(pdf.size())), "EncapsulatedDocumentLength");
  if (pdf.size() % 2) pdf.push_back(0);  // OB values have even length; the length above is the PDF's own
  check(ds.putAndInsertUint8Array(DCM_EncapsulatedDocument, pdf.data(), static_cast<unsigned long>(pdf.size())), "EncapsulatedDocument");
}

}  // namespace

Written write_encapsulated_pdf(const std::string& pdf_path, const DicomSource& source, const StudyContext& study,
                               const std::string& path) {
  std::vector<Uint8> pdf = read_pdf(pdf_path);
  DcmFileFormat file;
  DcmDataset& ds = *file.getDataset();
  check(ds.putAndInsertString(DCM_SOPClassUID, UID_EncapsulatedPDFStorage), "SOPClassUID");
  check(ds.putAndInsertString(DCM_SOPInstanceUID, new_uid().c_str()), "SOPInstanceUID");
  apply_output_series(ds, study, source, "DOC", 9703, "MandiSym report");
  ds.findAndDeleteElement(DCM_FrameOfReferenceUID);  // a document has no frame of reference
  check(ds.putAndInsertString(DCM_ConversionType, "WSD"), "ConversionType");  // SC Equipment: workstation
  add_document(ds, std::move(pdf));
  add_source_instances(ds, source);
  return save(file, path, "PDF");
}

}  // namespace ms::dicomout
