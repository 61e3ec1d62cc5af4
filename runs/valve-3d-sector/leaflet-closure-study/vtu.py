import base64, struct, re
def read(path):
    s=open(path).read()
    out={}
    for m in re.finditer(r'<DataArray type="(\w+)" Name="(\w+)" NumberOfComponents="(\d+)" format="binary">\s*([^<]*)</DataArray>', s):
        t,name,nc,data=m.group(1),m.group(2),int(m.group(3)),m.group(4).strip()
        raw=base64.b64decode(data)
        n=struct.unpack('<Q',raw[:8])[0]
        fmt={'Float64':'d','Int64':'q','UInt8':'B'}[t]
        sz=struct.calcsize(fmt)
        vals=struct.unpack('<%d%s'%(n//sz,fmt),raw[8:8+n])
        if nc>1: vals=[vals[i:i+nc] for i in range(0,len(vals),nc)]
        out[name]=list(vals)
    conn,offs=out['connectivity'],out['offsets']
    cells=[];st=0
    for o in offs: cells.append(conn[st:o]); st=o
    out['cells']=cells
    return out
